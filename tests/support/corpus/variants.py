"""Cell sources of the corpus: common mistakes and valid alternatives, as a student would write them.

Each constant is the full text of one notebook code cell (imports included), written to
replace the cell that defines the function in the answer key, or (``WRAP_*``) to be appended
after it: the wrapper keeps the key's function under another name and changes one thing.
"""

# --------------------------------------------------------------------------- Q2 mistakes

EIGHTPOINT_TRANSPOSED = '''\
import numpy as np


def eightpoint(pts1, pts2, M, refine=False):
    """Eight-point algorithm; each row written as x1^T F x2 = 0 (the classic transposition)."""
    p1 = np.asarray(pts1, dtype=float) / M
    p2 = np.asarray(pts2, dtype=float) / M
    x1, y1 = p1.T
    x2, y2 = p2.T
    A = np.stack([x1 * x2, x1 * y2, x1, y1 * x2, y1 * y2, y1, x2, y2, np.ones_like(x1)], axis=1)
    F = np.linalg.svd(A)[2][-1].reshape(3, 3)
    U, S, Vt = np.linalg.svd(F)
    F = U @ np.diag([S[0], S[1], 0.0]) @ Vt
    T = np.diag([1 / M, 1 / M, 1.0])
    F = T.T @ F @ T
    return F / np.linalg.norm(F)
'''

EIGHTPOINT_RANK3 = '''\
import numpy as np


def eightpoint(pts1, pts2, M, refine=False):
    """Eight-point algorithm without the rank-2 step."""
    p1 = np.asarray(pts1, dtype=float) / M
    p2 = np.asarray(pts2, dtype=float) / M
    x1, y1 = p1.T
    x2, y2 = p2.T
    A = np.stack([x2 * x1, x2 * y1, x2, y2 * x1, y2 * y1, y2, x1, y1, np.ones_like(x1)], axis=1)
    F = np.linalg.svd(A)[2][-1].reshape(3, 3)
    T = np.diag([1 / M, 1 / M, 1.0])
    F = T.T @ F @ T
    return F / np.linalg.norm(F)
'''

EIGHTPOINT_NOT_UNSCALED = '''\
import numpy as np


def eightpoint(pts1, pts2, M, refine=False):
    """Eight-point algorithm that forgets to unscale F."""
    p1 = np.asarray(pts1, dtype=float) / M
    p2 = np.asarray(pts2, dtype=float) / M
    x1, y1 = p1.T
    x2, y2 = p2.T
    A = np.stack([x2 * x1, x2 * y1, x2, y2 * x1, y2 * y1, y2, x1, y1, np.ones_like(x1)], axis=1)
    F = np.linalg.svd(A)[2][-1].reshape(3, 3)
    U, S, Vt = np.linalg.svd(F)
    F = U @ np.diag([S[0], S[1], 0.0]) @ Vt
    return F / np.linalg.norm(F)
'''

# Right on float points; products of the raw uint16 coordinates wrap around.
EIGHTPOINT_UINT16 = '''\
import numpy as np


def eightpoint(pts1, pts2, M, refine=False):
    """Eight-point algorithm on raw pixel products, the columns scaled afterwards."""
    x1, y1 = pts1[:, 0], pts1[:, 1]
    x2, y2 = pts2[:, 0], pts2[:, 1]
    A = np.stack([x2 * x1, x2 * y1, x2, y2 * x1, y2 * y1, y2, x1, y1, np.ones(len(x1))], axis=1)
    D = np.array([1 / M**2, 1 / M**2, 1 / M, 1 / M**2, 1 / M**2, 1 / M, 1 / M, 1 / M, 1.0])
    f = np.linalg.svd(A * D)[2][-1]
    F = (f * D).reshape(3, 3)
    U, S, Vt = np.linalg.svd(F)
    F = U @ np.diag([S[0], S[1], 0.0]) @ Vt
    return F / np.linalg.norm(F)
'''

# --------------------------------------------------------------------------- Q2 alternatives

EIGHTPOINT_HARTLEY = '''\
import numpy as np


def _normaliser(p):
    c = p.mean(axis=0)
    s = np.sqrt(2) / np.mean(np.linalg.norm(p - c, axis=1))
    return np.array([[s, 0, -s * c[0]], [0, s, -s * c[1]], [0, 0, 1.0]])


def eightpoint(pts1, pts2, M):
    """Eight-point algorithm with Hartley's normalisation (M is not needed)."""
    p1 = np.asarray(pts1, dtype=float)
    p2 = np.asarray(pts2, dtype=float)
    T1, T2 = _normaliser(p1), _normaliser(p2)
    h1 = np.column_stack([p1, np.ones(len(p1))]) @ T1.T
    h2 = np.column_stack([p2, np.ones(len(p2))]) @ T2.T
    A = np.einsum("ni,nj->nij", h2, h1).reshape(len(p1), 9)
    F = np.linalg.svd(A)[2][-1].reshape(3, 3)
    U, S, Vt = np.linalg.svd(F)
    F = T2.T @ (U @ np.diag([S[0], S[1], 0.0]) @ Vt) @ T1
    return F / np.linalg.norm(F)
'''

EIGHTPOINT_NO_REFINE = '''\
import numpy as np


def eightpoint(pts1, pts2, M):
    """The handout's eight-point algorithm (scaled by 1/M), without refineF."""
    p1 = np.asarray(pts1, dtype=float) / M
    p2 = np.asarray(pts2, dtype=float) / M
    x1, y1 = p1.T
    x2, y2 = p2.T
    A = np.stack([x2 * x1, x2 * y1, x2, y2 * x1, y2 * y1, y2, x1, y1, np.ones_like(x1)], axis=1)
    F = np.linalg.svd(A)[2][-1].reshape(3, 3)
    U, S, Vt = np.linalg.svd(F)
    F = U @ np.diag([S[0], S[1], 0.0]) @ Vt
    T = np.diag([1 / M, 1 / M, 1.0])
    return T.T @ F @ T
'''

# --------------------------------------------------------------------------- Q3 mistakes

ESSENTIAL_K_SWAPPED = '''\
def essentialMatrix(F, K1, K2):
    """E with the intrinsics on the wrong sides."""
    return K1.T @ F @ K2
'''

TRIANGULATE_MEAN_ERROR = '''\
import numpy as np


def triangulate(C1, pts1, C2, pts2):
    """Linear triangulation that reports the mean squared error per point instead of the sum."""
    p1 = np.asarray(pts1, dtype=float)
    p2 = np.asarray(pts2, dtype=float)
    w = np.zeros((len(p1), 3))
    for i, ((x1, y1), (x2, y2)) in enumerate(zip(p1, p2)):
        A = np.array([x1 * C1[2] - C1[0], y1 * C1[2] - C1[1], x2 * C2[2] - C2[0], y2 * C2[2] - C2[1]])
        X = np.linalg.svd(A)[2][-1]
        w[i] = X[:3] / X[3]
    hom = np.column_stack([w, np.ones(len(w))])
    err = 0.0
    for C, p in ((C1, p1), (C2, p2)):
        h = hom @ C.T
        err += np.sum((p - h[:, :2] / h[:, 2:]) ** 2)
    return w, err / len(w)
'''

FINDM2_CHEIRALITY_FLIPPED = '''\
import numpy as np
from starter import camera2


def findM2(F, pts1, pts2, K1, K2):
    """Chooses among the four cameras with the depth test's sign flipped."""
    M2s = camera2(essentialMatrix(F, K1, K2))
    C1 = K1 @ np.hstack([np.eye(3), np.zeros((3, 1))])
    best = None
    for i in range(4):
        M2 = M2s[:, :, i]
        w, err = triangulate(C1, pts1, K2 @ M2, pts2)
        behind = np.sum((w[:, 2] < 0) & (w @ M2[2, :3] + M2[2, 3] < 0))
        if best is None or behind > best[0]:
            best = (behind, M2, K2 @ M2, w)
    return best[1], best[2], best[3]
'''

# --------------------------------------------------------------------------- Q4-Q6 mistakes (wrappers)

WRAP_XY_SWAPPED = '''\
_key_epipolarCorrespondence = epipolarCorrespondence


def epipolarCorrespondence(im1, im2, F, x1, y1):
    """Returns the match as (row, column) instead of (x, y)."""
    x2, y2 = _key_epipolarCorrespondence(im1, im2, F, x1, y1)
    return y2, x2
'''

WRAP_RESIDUAL_INTERLEAVED = '''\
import numpy as np

_key_rodriguesResidual = rodriguesResidual


def rodriguesResidual(K1, M1, p1, K2, p2, x):
    """The right residuals, but image 1 and image 2 interleaved point by point."""
    r = _key_rodriguesResidual(K1, M1, p1, K2, p2, x)
    n = len(p1)
    return np.hstack([r[:2 * n].reshape(n, 2), r[2 * n:].reshape(n, 2)]).ravel()
'''

BA_RETURNS_START = '''\
import numpy as np
import scipy.optimize
from starter import invRodrigues, rodrigues


def bundleAdjustment(K1, M1, p1, K2, M2_init, p2, w_init):
    """Optimises, then unpacks x0 instead of the optimiser's result."""
    n = len(p1)
    x0 = np.concatenate([w_init.ravel(), invRodrigues(M2_init[:, :3]), M2_init[:, 3]])
    fit = scipy.optimize.least_squares(lambda x: rodriguesResidual(K1, M1, p1, K2, p2, x), x0)
    x = x0
    M2 = np.hstack([rodrigues(x[3 * n:3 * n + 3]), x[3 * n + 3:, None]])
    o1 = float(np.sum(rodriguesResidual(K1, M1, p1, K2, p2, x0) ** 2))
    return M2, x[:3 * n].reshape(n, 3), o1, float(np.sum(fit.fun ** 2))
'''

# The handout's way: scipy.optimize.minimize on the sum of squares, nothing to fix the scale.
BA_MINIMIZE = '''\
import numpy as np
import scipy.optimize
from starter import invRodrigues, rodrigues


def bundleAdjustment(K1, M1, p1, K2, M2_init, p2, w_init):
    """Bundle adjustment with scipy.optimize.minimize, as the handout suggests."""
    p1 = np.asarray(p1, dtype=float)
    p2 = np.asarray(p2, dtype=float)
    n = len(p1)

    def cost(x):
        return np.sum(rodriguesResidual(K1, M1, p1, K2, p2, x) ** 2)

    x0 = np.concatenate([np.asarray(w_init, float).ravel(), invRodrigues(M2_init[:, :3]), M2_init[:, 3]])
    x = scipy.optimize.minimize(cost, x0).x
    M2 = np.hstack([rodrigues(x[3 * n:3 * n + 3]), x[3 * n + 3:, None]])
    return M2, x[:3 * n].reshape(n, 3), float(cost(x0)), float(cost(x))
'''

# A plain scipy least_squares on the handout's residuals: no gauge fixed, so the scale of the
# scene (|t| with the points) drifts freely (with x_scale="jac" it grows about 30-fold on the
# public scene); any scale is a right answer.
BA_LEAST_SQUARES = '''\
import numpy as np
import scipy.optimize
from starter import invRodrigues, rodrigues


def bundleAdjustment(K1, M1, p1, K2, M2_init, p2, w_init):
    """Bundle adjustment with scipy.optimize.least_squares, nothing held fixed."""
    p1 = np.asarray(p1, dtype=float)
    p2 = np.asarray(p2, dtype=float)
    n = len(p1)
    x0 = np.concatenate([np.asarray(w_init, float).ravel(), invRodrigues(M2_init[:, :3]), M2_init[:, 3]])
    fit = scipy.optimize.least_squares(lambda x: rodriguesResidual(K1, M1, p1, K2, p2, x), x0, x_scale="jac")
    x = fit.x
    M2 = np.hstack([rodrigues(x[3 * n:3 * n + 3]), x[3 * n + 3:, None]])
    o1 = float(np.sum(rodriguesResidual(K1, M1, p1, K2, p2, x0) ** 2))
    return M2, x[:3 * n].reshape(n, 3), o1, float(np.sum(fit.fun ** 2))
'''

WRAP_THRESHOLD_INCLUSIVE = '''\
_key_MultiviewReconstruction = MultiviewReconstruction


def MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres):
    """Uses the detections whose confidence is >= Thres (one too many)."""
    return _key_MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres - 0.5)
'''

# --------------------------------------------------------------------------- self-check variants via refineF
# Cells as a student would write them in the notebook, where ``refineF`` is the name imported
# by the notebook's import cell: the self-checks must name each mistake also when refineF is
# called (it polishes a transposed F into a near miss and returns rank 2 whatever it is given),
# and pass each valid method.  ``eightpoint_cell`` writes one; the constants below are the ones
# the tests and the grading tests use by name.

_ROW_RIGHT = "x2 * x1, x2 * y1, x2, y2 * x1, y2 * y1, y2, x1, y1, np.ones_like(x1)"
_ROW_TRANSPOSED = "x1 * x2, x1 * y2, x1, y1 * x2, y1 * y2, y1, x2, y2, np.ones_like(x1)"


def eightpoint_cell(mistake=None, refine=False, solver="svd", refine_after_unscaling=False):
    """The text of a notebook cell defining ``eightpoint(pts1, pts2, M)`` (1/M scaling) with one
    of the catalogue's Q2 mistakes (a code of judging.mistakes.KNOWN_MISTAKES, or None).

    refine : call ``refineF`` (before unscaling, on the scaled F and points, as the handout
        suggests; or after it, on the pixel F and points, which the FAQ allows too).
    solver : "svd" (right singular vector) or "eigh" (eigenvector of A^T A): both are right.
    """
    row = _ROW_TRANSPOSED if mistake == "f_transposed" else _ROW_RIGHT
    coords = ("y1, x1 = p1.T\n    y2, x2 = p2.T" if mistake == "xy_swapped" else "x1, y1 = p1.T\n    x2, y2 = p2.T")
    solve = ("F = np.linalg.svd(A)[2][-1].reshape(3, 3)" if solver == "svd"
             else "F = np.linalg.eigh(A.T @ A)[1][:, 0].reshape(3, 3)")
    rank2 = "" if mistake == "f_rank3" else "U, S, Vt = np.linalg.svd(F)\n    F = U @ np.diag([S[0], S[1], 0.0]) @ Vt"
    unscale = {"f_not_unscaled": "", "f_unscaled_wrong_way": "S = np.diag([M, M, 1.0])\n    F = S @ F @ S"}.get(
        mistake, "F = T.T @ F @ T")
    if mistake == "uint16_wraparound":
        # Products of the raw coordinates in their own dtype (uint16 wraps around), columns scaled after.
        build = ("x1, y1 = pts1[:, 0], pts1[:, 1]\n    x2, y2 = pts2[:, 0], pts2[:, 1]\n"
                 f"    A = np.stack([{row.replace('np.ones_like(x1)', 'np.ones(len(x1))')}], axis=1)\n"
                 "    A = A * np.array([1 / M**2, 1 / M**2, 1 / M, 1 / M**2, 1 / M**2, 1 / M, 1 / M, 1 / M, 1.0])\n"
                 "    p1 = np.asarray(pts1, dtype=float) / M\n    p2 = np.asarray(pts2, dtype=float) / M")
    else:
        build = ("p1 = np.asarray(pts1, dtype=float) / M\n    p2 = np.asarray(pts2, dtype=float) / M\n"
                 f"    {coords}\n    A = np.stack([{row}], axis=1)")
    before = "F = refineF(F, p1, p2)" if refine and not refine_after_unscaling else ""
    after = "F = refineF(F, pts1, pts2)" if refine and refine_after_unscaling else ""
    body = "\n    ".join(line for line in [build, solve, rank2, before, "T = np.diag([1 / M, 1 / M, 1.0])", unscale,
                                           after, "return F / np.linalg.norm(F)"] if line)
    return f"import numpy as np\n\n\ndef eightpoint(pts1, pts2, M):\n    {body}\n"


# A mistake that refineF hides (the FAQ's "comment out the call to refineF").
EIGHTPOINT_TRANSPOSED_REFINED = eightpoint_cell("f_transposed", refine=True)
# Valid: no SVD rank-2 step of its own, but refineF (before unscaling) returns rank 2, switched off too.
EIGHTPOINT_RANK3_REFINED = eightpoint_cell("f_rank3", refine=True)
# Valid: refineF after unscaling (FAQ Q2.1), and the null vector from eigh instead of the SVD.
EIGHTPOINT_REFINED_AFTER_UNSCALING = eightpoint_cell(refine=True, refine_after_unscaling=True)
EIGHTPOINT_EIGH_REFINED = eightpoint_cell(refine=True, solver="eigh")

_TRIANGULATE = '''\
import numpy as np


def triangulate(C1, pts1, C2, pts2):
    """Linear triangulation, {what}."""
    p1 = np.asarray(pts1, dtype=float)
    p2 = np.asarray(pts2, dtype=float)
    w = np.zeros((len(p1), 3))
    points = np.zeros((len(p1), 3))
    for i, ((x1, y1), (x2, y2)) in enumerate(zip(p1, p2)):
        A = np.array([x1 * C1[2] - C1[0], y1 * C1[2] - C1[1], x2 * C2[2] - C2[0], y2 * C2[2] - C2[1]])
        X = np.linalg.svd(A)[2][-1]
        points[i] = X[:3] / X[3]
        w[i] = {row}
    hom = np.column_stack([{err_of}, np.ones(len(w))])
    err = 0.0
    for C, p in ((C1, p1), (C2, p2)):
        h = hom @ C.T
        err += np.sum((p - h[:, :2] / h[:, 2:]) ** 2)
    return w, err
'''
# w = X[:3] of the homogeneous solution; err computed from the divided points (as meant).
TRIANGULATE_W_NOT_DIVIDED = _TRIANGULATE.format(what="w returned undivided, err of the divided points",
                                                row="X[:3]", err_of="points")
# The same, err computed from the w returned (consistent with it).
TRIANGULATE_W_NOT_DIVIDED_OWN_ERR = _TRIANGULATE.format(what="w returned undivided, err of that w",
                                                        row="X[:3]", err_of="w")
# The points mirrored through camera 1's centre (a sign lost): behind both cameras.
TRIANGULATE_POINTS_MIRRORED = _TRIANGULATE.format(what="every point mirrored (its sign lost)",
                                                  row="-X[:3] / X[3]", err_of="w")

# A matcher with another window score (sum of absolute differences, no weighting) and its own
# window and search range: valid.
EPIPOLAR_SAD = '''\
import numpy as np


def epipolarCorrespondence(im1, im2, F, x1, y1):
    """Along the epipolar line, the pixel whose 9 x 9 window differs least (sum of absolute differences)."""
    im1 = np.asarray(im1, dtype=float)
    im2 = np.asarray(im2, dtype=float)
    H, W = im2.shape[:2]
    h = 4
    a, b, c = F @ np.array([x1, y1, 1.0])
    if abs(a) >= abs(b):  # closer to vertical: one candidate per row
        ys = np.arange(y1 - 30, y1 + 31)
        xs = np.rint(-(b * ys + c) / a).astype(int)
    else:
        xs = np.arange(x1 - 30, x1 + 31)
        ys = np.rint(-(a * xs + c) / b).astype(int)
    keep = (xs >= h) & (xs < W - h) & (ys >= h) & (ys < H - h)
    ys, xs = ys[keep], xs[keep]
    r0, c0 = min(max(y1, h), H - 1 - h), min(max(x1, h), W - 1 - h)
    ref = im1[r0 - h:r0 + h + 1, c0 - h:c0 + h + 1]
    scores = [np.abs(im2[y - h:y + h + 1, x - h:x + h + 1] - ref).sum() for x, y in zip(xs, ys)]
    k = int(np.argmin(scores))
    return int(xs[k]), int(ys[k])
'''

# The classic indexing slip: im[x, y] instead of im[y, x]; near the border the windows differ
# in shape and numpy raises (the self-check must point to this cell's line).
EPIPOLAR_INDEXED_XY = EPIPOLAR_SAD.replace(
    "ref = im1[r0 - h:r0 + h + 1, c0 - h:c0 + h + 1]", "ref = im1[c0 - h:c0 + h + 1, r0 - h:r0 + h + 1]")
# The polished transposed F with refineF after unscaling (on the pixel F and points).
EIGHTPOINT_TRANSPOSED_REFINED_AFTER_UNSCALING = eightpoint_cell("f_transposed", refine=True,
                                                                refine_after_unscaling=True)

# Valid: Hartley's normalisation, refineF on the normalised F and points, then unnormalised.
EIGHTPOINT_HARTLEY_REFINED = EIGHTPOINT_HARTLEY.replace(
    "    F = T2.T @ (U @ np.diag([S[0], S[1], 0.0]) @ Vt) @ T1\n",
    "    F = refineF(U @ np.diag([S[0], S[1], 0.0]) @ Vt, h1[:, :2], h2[:, :2])\n    F = T2.T @ F @ T1\n")
assert EIGHTPOINT_HARTLEY_REFINED != EIGHTPOINT_HARTLEY

# --------------------------------------------------------------------------- the course's call conventions
# Matchers written for the course's call (Python int coordinates, float images in [0, 1]):
# one slices its windows with the coordinates as given (a float coordinate raises TypeError),
# one subtracts the windows in the images' own dtype (uint8 wraps around; floats are fine).
EPIPOLAR_SLICES_WITH_COORDINATES = EPIPOLAR_SAD.replace(
    "    r0, c0 = min(max(y1, h), H - 1 - h), min(max(x1, h), W - 1 - h)\n", "    r0, c0 = y1, x1\n")
assert EPIPOLAR_SLICES_WITH_COORDINATES != EPIPOLAR_SAD
EPIPOLAR_UINT8_DIFFERENCES = EPIPOLAR_SAD.replace(
    "    im1 = np.asarray(im1, dtype=float)\n    im2 = np.asarray(im2, dtype=float)\n",
    "    x1, y1 = int(round(x1)), int(round(y1))\n")
assert EPIPOLAR_UINT8_DIFFERENCES != EPIPOLAR_SAD

# Another year's findM2 (2022-2024): K1 and K2 in one dict, a file name to save the result into.
FINDM2_INTRINSICS = '''\
import numpy as np
from starter.pose import camera2


def findM2(F, pts1, pts2, intrinsics, filename="q3_3.npz"):
    """The candidate of camera2 with the most points in front of both cameras; intrinsics {'K1', 'K2'}."""
    K1, K2 = intrinsics["K1"], intrinsics["K2"]
    E = K2.T @ F @ K1
    C1 = K1 @ np.hstack([np.eye(3), np.zeros((3, 1))])
    best = None
    for k in range(4):
        M2 = camera2(E)[:, :, k]
        C2 = K2 @ M2
        w, err = triangulate(C1, pts1, C2, pts2)
        front = np.sum((w[:, 2] > 0) & ((w @ M2[:, :3].T + M2[:, 3])[:, 2] > 0))
        if best is None or front > best[0]:
            best = (front, M2, C2, w)
    return best[1], best[2], best[3]
'''
# The same signature, but indexing the intrinsics as a list (fails on the course's dict).
FINDM2_INTRINSICS_BROKEN = FINDM2_INTRINSICS.replace('K1, K2 = intrinsics["K1"], intrinsics["K2"]',
                                                     "K1, K2 = intrinsics[0], intrinsics[1]")

# Another year's compute3D_pts (2022-2024): five arguments, the cameras from the student's findM2.
COMPUTE3D_FIVE_ARGUMENTS = '''\
import numpy as np


def compute3D_pts(temple_pts1, intrinsics, F, im1, im2):
    """Match templeCoords along the epipolar lines, find M2 from the matches, triangulate; returns P."""
    K1, K2 = intrinsics["K1"], intrinsics["K2"]
    pts1 = np.asarray(temple_pts1)
    pts2 = np.array([epipolarCorrespondence(im1, im2, F, int(x), int(y)) for x, y in pts1], dtype=float)
    M2, C2, P = findM2(F, pts1.astype(float), pts2, K1, K2)
    return P
'''

# --------------------------------------------------------------------------- each returned value checked
# Every value a function returns is judged against the points it returned itself: these return
# right points with one inconsistent companion value, and must lose exactly the check of that value.
WRAP_MULTIVIEW_MEAN_ERR = '''\
import numpy as np

_key_MultiviewReconstruction = MultiviewReconstruction


def MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres):
    """The right P, but err the mean over the detections used instead of their total."""
    P, err = _key_MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres)
    confident = np.stack([np.asarray(p)[:, 2] > Thres for p in (pts1, pts2, pts3)], axis=1)
    used = confident[confident.sum(axis=1) >= 2].sum()
    return P, err / max(int(used), 1)
'''

# compute3D_pts's right w, but the points of image 1 returned as pts2 (the wrong array returned).
WRAP_COMPUTE3D_RETURNS_PTS1 = '''\
import numpy as np

_key_compute3D_pts = compute3D_pts


def compute3D_pts(im1, im2, F, x1, y1, C1, C2):
    """The right points w, but returns the coordinates of image 1 as the matches pts2."""
    w, pts2 = _key_compute3D_pts(im1, im2, F, x1, y1, C1, C2)
    return w, np.column_stack([np.ravel(x1), np.ravel(y1)]).astype(float)
'''
