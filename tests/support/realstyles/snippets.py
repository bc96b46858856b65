"""Function sources in the styles real hand-ins of 2018-2025 use, written for this corpus.

Each constant is the text of one function as a student writes it in a given year's file (the
file's imports are the layout's business, see ``__init__``): the names a snippet needs from
``helper`` or SciPy are listed in ``NEEDS`` so the layout can import them the year's way.
Nothing here is copied from a hand-in: the habits (``refineF`` on the raw 3x3, ``E / E[2, 2]``,
``findM2(F, pts1, pts2, intrinsics, filename)``, fixed windows with no padding, ``result/``
writes, ``scipy.optimize.minimize`` on the summed squares...) are.
"""

# --------------------------------------------------------------------------- Q2 eightpoint

_EP_HEAD = '''\
def eightpoint(pts1, pts2, M{extra}):
    {pre}
    T = np.array([[1.0 / M, 0, 0], [0, 1.0 / M, 0], [0, 0, 1]])
    x1, y1 = p1[:, 0], p1[:, 1]
    x2, y2 = p2[:, 0], p2[:, 1]
    A = np.vstack(({row})).T
    U, S, Vt = np.linalg.svd(A)
'''

_ROW = "x2 * x1, x2 * y1, x2, y2 * x1, y2 * y1, y2, x1, y1, np.ones(len(x1))"
_ROW_T = "x1 * x2, x1 * y2, x1, y1 * x2, y1 * y2, y1, x2, y2, np.ones(len(x1))"
_CAST = "p1 = pts1.astype(np.float64) / M\n    p2 = pts2.astype(np.float64) / M"


def _ep(tail, *, row=_ROW, pre=_CAST, extra=""):
    return _EP_HEAD.format(row=row, pre=pre, extra=extra) + tail


# 2022-24: refineF on the raw 3x3 (refineF singularizes), then unscale; rank 2 by refineF only.
EP_REFINE_RAW = _ep('''\
    F = refineF(Vt[-1].reshape(3, 3), p1, p2)
    F = T.T @ F @ T
    return F
''')

# 2018-21 submission.py: SVD rank 2, then helper.refineF through the module, then unscale.
EP_SVD_THEN_HELPER_REFINE = _ep('''\
    F = Vt[-1].reshape(3, 3)
    u, s, vt = np.linalg.svd(F)
    s[2] = 0
    F = u @ np.diag(s) @ vt
    F = helper.refineF(F, p1, p2)
    F = np.dot(T.T, np.dot(F, T))
    return F
''')

# A course helper took refineF(f, ...) with f the 9-vector (it reshaped it): students passed Vt[-1].
EP_REFINE_NINE_VECTOR = _ep('''\
    F = refineF(Vt[-1], p1, p2)
    F = T.T @ F @ T
    F = F / F[2, 2]
    return F
''')

# refineF bound as a default argument (a "switch" the student kept in the signature).
EP_REFINE_DEFAULT_ARG = _ep('''\
    F = Vt[-1].reshape(3, 3)
    if refine is not None:
        F = refine(F, p1, p2)
    else:
        F = _singularize(F)
    return T.T @ F @ T
''', extra=", refine=refineF")

# refineF imported inside the function (a habit of students who moved code between files).
EP_REFINE_IMPORTED_INSIDE = _ep('''\
    from helper import refineF
    F = refineF(Vt[-1].reshape(3, 3), p1, p2)
    return T.T @ F @ T
''')

# No refineF at all; rank 2 by SVD; F normalised by its norm.
EP_SVD_ONLY = _ep('''\
    F = Vt[-1].reshape(3, 3)
    U2, S2, V2 = np.linalg.svd(F)
    F = U2 @ np.diag([S2[0], S2[1], 0.0]) @ V2
    F = T.T @ F @ T
    return F / np.linalg.norm(F)
''')

# 2018-21 drivers ran from python/ and saved beside the data: np.savez('../data/q2_1.npz', ...).
EP_SAVES_TO_DATA = _ep('''\
    F = _singularize(Vt[-1].reshape(3, 3))
    F = helper.refineF(F, p1, p2)
    F = T.T.dot(F).dot(T)
    np.savez('../data/q2_1.npz', F=F, M=M)
    return F
''')

# --- Q2 mistakes
# The transposed design matrix, polished by helper.refineF (2018-21 style): FAQ's 94 / 1927.
EP_TRANSPOSED_HELPER_REFINE = _ep('''\
    F = Vt[-1].reshape(3, 3)
    F = helper.refineF(F, p1, p2)
    F = np.dot(T.T, np.dot(F, T))
    return F
''', row=_ROW_T)

# The transposed design matrix, refineF imported inside the function.
EP_TRANSPOSED_REFINE_INSIDE = _ep('''\
    from helper import refineF
    F = refineF(Vt[-1].reshape(3, 3), p1, p2)
    return T.T @ F @ T
''', row=_ROW_T)

# The transposed design matrix, refineF bound as a default argument.
EP_TRANSPOSED_REFINE_DEFAULT_ARG = _ep('''\
    F = refine(Vt[-1].reshape(3, 3), p1, p2)
    return T.T @ F @ T
''', row=_ROW_T, extra=", refine=refineF")

# Rank 2 never enforced (no refineF, no SVD step).
EP_RANK3 = _ep('''\
    F = Vt[-1].reshape(3, 3)
    F = T.T @ F @ T
    return F / F[2, 2]
''')

# refineF'd but never unscaled.
EP_NOT_UNSCALED = _ep('''\
    F = refineF(Vt[-1].reshape(3, 3), p1, p2)
    return F
''')

# In-place division (F23 habit): fails on the official uint16 points ("pts1 /= M").
EP_INPLACE_DIVIDE = _ep('''\
    F = _singularize(Vt[-1].reshape(3, 3))
    F = T.T @ F @ T
    return F
''', pre="pts1 /= M\n    pts2 /= M\n    p1, p2 = pts1, pts2")

# --------------------------------------------------------------------------- Q3.1 essentialMatrix

ESS_E22 = '''\
def essentialMatrix(F, K1, K2):
    E = K2.T @ F @ K1
    E = E / E[2, 2]
    return E
'''

ESS_NORM = '''\
def essentialMatrix(F, K1, K2):
    E = np.dot(np.transpose(K2), np.dot(F, K1))
    return E / np.linalg.norm(E)
'''

ESS_PLAIN = '''\
def essentialMatrix(F, K1, K2):
    return K2.T.dot(F).dot(K1)
'''

# Mistake: E = K1^T F K2.
ESS_SWAPPED = '''\
def essentialMatrix(F, K1, K2):
    E = K1.T @ F @ K2
    return E
'''

# --------------------------------------------------------------------------- Q3.2 triangulate

TRI_LOOP = '''\
def triangulate(C1, pts1, C2, pts2):
    n = pts1.shape[0]
    P = np.zeros((n, 3))
    err = 0
    for i in range(n):
        x1, y1 = pts1[i, 0], pts1[i, 1]
        x2, y2 = pts2[i, 0], pts2[i, 1]
        A = np.array([y1 * C1[2, :] - C1[1, :],
                      C1[0, :] - x1 * C1[2, :],
                      y2 * C2[2, :] - C2[1, :],
                      C2[0, :] - x2 * C2[2, :]])
        _, _, vh = np.linalg.svd(A)
        X = vh[-1] / vh[-1][3]
        P[i] = X[:3]
        a = C1 @ X
        b = C2 @ X
        err += np.sum((a[:2] / a[2] - pts1[i]) ** 2) + np.sum((b[:2] / b[2] - pts2[i]) ** 2)
    return P, err
'''

TRI_VECTOR = '''\
def triangulate(C1, pts1, C2, pts2):
    pts1 = np.asarray(pts1, dtype=float)
    pts2 = np.asarray(pts2, dtype=float)
    A = np.stack([pts1[:, [0]] * C1[2] - C1[0], pts1[:, [1]] * C1[2] - C1[1],
                  pts2[:, [0]] * C2[2] - C2[0], pts2[:, [1]] * C2[2] - C2[1]], axis=1)
    Xh = np.linalg.svd(A)[2][:, -1, :]
    Xh = Xh / Xh[:, 3:]
    q1 = Xh @ C1.T
    q2 = Xh @ C2.T
    q1 = q1[:, :2] / q1[:, 2:]
    q2 = q2[:, :2] / q2[:, 2:]
    err = np.sum((q1 - pts1) ** 2) + np.sum((q2 - pts2) ** 2)
    return Xh[:, :3], err
'''

# --------------------------------------------------------------------------- Q3.3 findM2

_FM_BODY = '''\
    M1 = np.hstack((np.eye(3), np.zeros((3, 1))))
    C1 = K1 @ M1
    E = essentialMatrix(F, K1, K2)
    M2s = camera2(E)
    best = None
    for i in range(M2s.shape[2]):
        M2 = M2s[:, :, i]
        C2 = K2 @ M2
        P, err = triangulate(C1, pts1, C2, pts2)
{choose}
    M2, C2, P = best[1:]
{save}    return M2, C2, P
'''

_FM_BOTH = '''\
        depth2 = (np.hstack((P, np.ones((len(P), 1)))) @ M2.T)[:, 2]
        if np.all(P[:, 2] > 0) and np.all(depth2 > 0):
            best = (err, M2, C2, P)
'''
# Mistake: depth in camera 1 only, keeping the smallest error among those.
_FM_CAM1 = '''\
        if np.all(P[:, 2] > 0) and (best is None or err < best[0]):
            best = (err, M2, C2, P)
'''
# Both cameras, most points in front (robust to a stray point behind): count, then error.
_FM_COUNT = '''\
        depth2 = (np.hstack((P, np.ones((len(P), 1)))) @ M2.T)[:, 2]
        score = np.sum(P[:, 2] > 0) + np.sum(depth2 > 0)
        if best is None or score > best[0]:
            best = (score, M2, C2, P)
'''


def _fm(choose, *, intrinsics=False, save=""):
    head = ("def findM2(F, pts1, pts2, intrinsics, filename='q3_3.npz'):\n"
            "    K1, K2 = intrinsics['K1'], intrinsics['K2']\n") if intrinsics else \
        "def findM2(F, pts1, pts2, K1, K2):\n"
    return head + _FM_BODY.format(choose=choose.rstrip("\n"), save=save)


FM_INTR_BOTH = _fm(_FM_BOTH, intrinsics=True, save="    np.savez(filename, M2=M2, C2=C2, P=P)\n")
FM_INTR_CAM1 = _fm(_FM_CAM1, intrinsics=True)
FM_K_COUNT = _fm(_FM_COUNT)
FM_K_BOTH = _fm(_FM_BOTH)

# --------------------------------------------------------------------------- Q4.1 epipolarCorrespondence

# Gaussian-weighted SSD on float images, local search along the line, fixed window, no padding.
EC_GAUSS_LOCAL = '''\
def epipolarCorrespondence(im1, im2, F, x1, y1):
    x1, y1 = int(round(x1)), int(round(y1))
    half = 7
    im1 = im1.astype(float)
    im2 = im2.astype(float)
    line = F @ np.array([x1, y1, 1.0])
    g = np.exp(-np.arange(-half, half + 1) ** 2 / (2 * 3.0 ** 2))
    weight = np.outer(g, g)
    if im1.ndim == 3:
        weight = weight[:, :, None]
    patch1 = im1[y1 - half:y1 + half + 1, x1 - half:x1 + half + 1]
    h, w = im2.shape[:2]
    best, best_xy = np.inf, (x1, y1)
    for y2 in range(max(half, y1 - 40), min(h - half, y1 + 41)):
        x2 = int(round(-(line[1] * y2 + line[2]) / line[0]))
        if x2 < half or x2 >= w - half:
            continue
        patch2 = im2[y2 - half:y2 + half + 1, x2 - half:x2 + half + 1]
        d = np.sum(weight * (patch1 - patch2) ** 2)
        if d < best:
            best, best_xy = d, (x2, y2)
    return best_xy
'''

# Whole line, SAD on 0-255 intensities (uint8 cast then int), float coordinates kept until the end.
EC_WHOLE_LINE_UINT8 = '''\
def epipolarCorrespondence(im1, im2, F, x1, y1):
    def gray(im):
        im = np.asarray(im)
        if im.dtype != np.uint8:
            im = (np.clip(im, 0, 1) * 255).astype(np.uint8)
        if im.ndim == 3:
            im = im.mean(axis=2)
        return im.astype(np.int32)
    g1, g2 = gray(im1), gray(im2)
    r = 5
    xi, yi = int(x1), int(y1)
    ref = g1[yi - r:yi + r + 1, xi - r:xi + r + 1]
    l = F.dot(np.array([float(x1), float(y1), 1.0]))
    l = l / np.sqrt(l[0] ** 2 + l[1] ** 2)
    h, w = g2.shape
    best = (np.inf, xi, yi)
    for y in range(r, h - r):
        x = int(-(l[1] * y + l[2]) / l[0])
        if r <= x < w - r:
            d = np.abs(g2[y - r:y + r + 1, x - r:x + r + 1] - ref).sum()
            if d < best[0]:
                best = (d, x, y)
    return best[1], best[2]
'''

# Mistake: the loop's variables shadow the result; it returns the point of image 1.
EC_RETURNS_X1Y1 = '''\
def epipolarCorrespondence(im1, im2, F, x1, y1):
    x1, y1 = int(x1), int(y1)
    s = 5
    line = F @ np.array([x1, y1, 1])
    win1 = im1[y1 - s:y1 + s + 1, x1 - s:x1 + s + 1].astype(float)
    best = np.inf
    x2, y2 = x1, y1
    for yy in range(max(s, y1 - 30), min(im2.shape[0] - s, y1 + 30)):
        xx = int(-(line[1] * yy + line[2]) / line[0])
        if s <= xx < im2.shape[1] - s:
            d = np.sum((win1 - im2[yy - s:yy + s + 1, xx - s:xx + s + 1]) ** 2)
            if d < best:
                best = d
                x2, y2 = x1, y1
    return x2, y2
'''

# Mistake: the line of x1 taken as F^T x1 (the line in image 1 of a point of image 2); SSD, 11 px,
# the whole line.
EC_WRONG_LINE = '''\
def epipolarCorrespondence(im1, im2, F, x1, y1):
    x1, y1 = int(x1), int(y1)
    r = 5
    a, b, c = F.T.dot(np.array([x1, y1, 1.0]))
    ref = im1[y1 - r:y1 + r + 1, x1 - r:x1 + r + 1].astype(float)
    h, w = im2.shape[:2]
    best, x2, y2 = np.inf, x1, y1
    for y in range(r, h - r):
        x = int(round(-(b * y + c) / a))
        if r <= x < w - r:
            d = np.sum((im2[y - r:y + r + 1, x - r:x + r + 1].astype(float) - ref) ** 2)
            if d < best:
                best, x2, y2 = d, x, y
    return x2, y2
'''

# Mistake: the right line, but only rows within 10 px of y1 (a search box kept from a tutorial):
# a match further along the line is never reached.
EC_SMALL_BOX = '''\
def epipolarCorrespondence(im1, im2, F, x1, y1):
    x1, y1 = int(x1), int(y1)
    r = 5
    l = F @ np.array([x1, y1, 1.0])
    ref = im1[y1 - r:y1 + r + 1, x1 - r:x1 + r + 1].astype(float)
    best, x2, y2 = np.inf, x1, y1
    for y in range(y1 - 10, y1 + 11):
        x = int(round(-(l[1] * y + l[2]) / l[0]))
        cand = im2[y - r:y + r + 1, x - r:x + r + 1].astype(float)
        if cand.shape != ref.shape:
            continue
        d = np.sum((cand - ref) ** 2)
        if d < best:
            best, x2, y2 = d, x, y
    return x2, y2
'''

# --------------------------------------------------------------------------- Q4.2 compute3D_pts

# 2022-24: five arguments, findM2 inside, returns P.
C3D_FIVE_P = '''\
def compute3D_pts(temple_pts1, intrinsics, F, im1, im2):
    if isinstance(temple_pts1, dict) or hasattr(temple_pts1, "files"):
        temple_pts1 = np.hstack([temple_pts1["x1"], temple_pts1["y1"]])
    temple_pts1 = np.asarray(temple_pts1)
    temple_pts2 = np.zeros((len(temple_pts1), 2))
    for i in range(len(temple_pts1)):
        temple_pts2[i] = epipolarCorrespondence(im1, im2, F, temple_pts1[i, 0], temple_pts1[i, 1])
    M2, C2, P = findM2(F, temple_pts1, temple_pts2, intrinsics)
    return P
'''

# Five arguments, writes result/q4_2.npz (the student's own folder) and returns the 3x4 M2.
C3D_FIVE_M2_RESULT = '''\
def compute3D_pts(temple_pts1, intrinsics, F, im1, im2):
    temple_pts1 = np.asarray(temple_pts1)
    pts2 = np.array([epipolarCorrespondence(im1, im2, F, x, y) for x, y in temple_pts1])
    M2, C2, P = findM2(F, temple_pts1, pts2, intrinsics)
    M1 = np.hstack((np.eye(3), np.zeros((3, 1))))
    C1 = intrinsics['K1'] @ M1
    np.savez('result/q4_2.npz', F=F, M1=M1, M2=M2, C1=C1, C2=C2)
    return M2
'''

# 2022-24: temple_pts1 is what np.load('templeCoords.npz') gives, indexed by name: x1 and y1 are
# N x 1 columns (an N x 2 array raises IndexError here; the course called it with the mapping).
C3D_FIVE_MAPPING = '''\
def compute3D_pts(temple_pts1, intrinsics, F, im1, im2):
    x1 = temple_pts1['x1']
    y1 = temple_pts1['y1']
    pts1 = np.hstack((x1, y1))
    pts2 = np.zeros(pts1.shape)
    for i in range(x1.shape[0]):
        pts2[i] = epipolarCorrespondence(im1, im2, F, x1[i, 0], y1[i, 0])
    M2, C2, P = findM2(F, pts1, pts2, intrinsics)
    return P
'''

# The kit's signature (a single notebook): returns w and the matches.
C3D_SEVEN = '''\
def compute3D_pts(im1, im2, F, x1, y1, C1, C2):
    x1 = np.asarray(x1).reshape(-1)
    y1 = np.asarray(y1).reshape(-1)
    pts2 = np.array([epipolarCorrespondence(im1, im2, F, int(a), int(b)) for a, b in zip(x1, y1)], dtype=float)
    pts1 = np.column_stack([x1, y1]).astype(float)
    w, err = triangulate(C1, pts1, C2, pts2)
    return w, pts2
'''

# The kit's signature, the points returned homogeneous (N x 4, last column 1), as triangulate's
# SVD gives them.
C3D_SEVEN_HOMOGENEOUS = '''\
def compute3D_pts(im1, im2, F, x1, y1, C1, C2):
    pts1 = np.hstack([np.reshape(x1, (-1, 1)), np.reshape(y1, (-1, 1))]).astype(float)
    pts2 = np.zeros_like(pts1)
    for i, (a, b) in enumerate(pts1):
        pts2[i] = epipolarCorrespondence(im1, im2, F, int(a), int(b))
    w, err = triangulate(C1, pts1, C2, pts2)
    return np.hstack([w, np.ones((len(w), 1))])
'''

# --------------------------------------------------------------------------- Q5

RR_PLAIN = '''\
def rodriguesResidual(K1, M1, p1, K2, p2, x):
    n = p1.shape[0]
    P = x[:3 * n].reshape(n, 3)
    r2 = x[3 * n:3 * n + 3]
    t2 = x[3 * n + 3:].reshape(3, 1)
    M2 = np.hstack((rodrigues(r2), t2))
    Ph = np.hstack((P, np.ones((n, 1)))).T
    a = K1 @ M1 @ Ph
    b = K2 @ M2 @ Ph
    p1_hat = (a[:2] / a[2]).T
    p2_hat = (b[:2] / b[2]).T
    residuals = np.concatenate([(p1 - p1_hat).reshape([-1]), (p2 - p2_hat).reshape([-1])])
    return residuals
'''

_BA_HEAD = '''\
def bundleAdjustment(K1, M1, p1, K2, M2_init, p2, P_init):
    n = p1.shape[0]
    r0 = invRodrigues(M2_init[:, :3]).reshape(-1)
    x0 = np.concatenate([P_init.reshape(-1), r0, M2_init[:, 3].reshape(-1)])
    res = lambda x: rodriguesResidual(K1, M1, p1, K2, p2, x)
    o1 = np.sum(res(x0) ** 2)
'''
_BA_TAIL = '''\
    P2 = x[:3 * n].reshape(n, 3)
    M2 = np.hstack((rodrigues(x[3 * n:3 * n + 3]), x[3 * n + 3:].reshape(3, 1)))
    o2 = np.sum(res(x) ** 2)
    return M2, P2, o1, o2
'''
BA_LSQ = _BA_HEAD + "    x = least_squares(res, x0).x\n" + _BA_TAIL
BA_MINIMIZE = _BA_HEAD + ("    obj = lambda x: np.sum(res(x) ** 2)\n"
                          "    x = scipy.optimize.minimize(obj, x0, method='L-BFGS-B', options={'maxiter': 500}).x\n"
                          + _BA_TAIL)

# --------------------------------------------------------------------------- Q6

MV_LOOP = '''\
def MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres):
    Cs = [C1, C2, C3]
    pts = [pts1, pts2, pts3]
    n = pts1.shape[0]
    P = np.zeros((n, 3))
    err = 0
    for i in range(n):
        rows = []
        for C, p in zip(Cs, pts):
            if p[i, 2] > Thres:
                rows.append(p[i, 1] * C[2] - C[1])
                rows.append(C[0] - p[i, 0] * C[2])
        if len(rows) < 4:
            P[i] = np.nan
            continue
        X = np.linalg.svd(np.array(rows))[2][-1]
        X = X / X[3]
        P[i] = X[:3]
        for C, p in zip(Cs, pts):
            if p[i, 2] > Thres:
                q = C @ X
                err += np.sum((q[:2] / q[2] - p[i, :2]) ** 2)
    return P, err
'''

# Mistake: with exactly two confident views it always triangulates from views 1 and 2 (written for
# the common case of view 3 occluded), so a keypoint seen confidently in views 1 and 3, or 2 and 3,
# uses a detection at or below Thres.
MV_VIEWS_1_2 = '''\
def MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres):
    n = pts1.shape[0]
    P = np.full((n, 3), np.nan)
    err = 0.0
    for i in range(n):
        good = [pts1[i, 2] > Thres, pts2[i, 2] > Thres, pts3[i, 2] > Thres]
        if sum(good) == 3:
            views = [(C1, pts1), (C2, pts2), (C3, pts3)]
        elif sum(good) == 2:
            views = [(C1, pts1), (C2, pts2)]
        else:
            continue
        A = []
        for C, p in views:
            A.append(p[i, 0] * C[2] - C[0])
            A.append(p[i, 1] * C[2] - C[1])
        X = np.linalg.svd(np.array(A))[2][-1]
        X = X / X[-1]
        P[i] = X[:3]
        for C, p in views:
            q = C @ X
            err += (q[0] / q[2] - p[i, 0]) ** 2 + (q[1] / q[2] - p[i, 1]) ** 2
    return P, err
'''

VIDEO = '''\
def plot_3d_keypoint_video(pts_3d_video):
    import matplotlib.pyplot as plt
    fig = plt.figure()
    ax = fig.add_subplot(111, projection='3d')
    for P in pts_3d_video:
        P = np.asarray(P)
        ax.scatter(P[:, 0], P[:, 1], P[:, 2], s=5)
    return fig
'''
