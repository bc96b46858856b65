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
