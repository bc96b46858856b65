import numpy as np


def eightpoint(pts1, pts2, M):
    """Normalised 8-point."""
    T = np.diag([1 / M, 1 / M, 1])
    N = len(pts1)
    h2 = np.column_stack([pts2, np.ones(N)]) @ T.T
    h1 = np.column_stack([pts1, np.ones(N)]) @ T.T
    A = np.column_stack([h2[:, 0:1] * h1, h2[:, 1:2] * h1, h1])
    f = np.linalg.svd(A.T @ A)[2][-1]
    Fn = f.reshape(3, 3)
    uu, dd, vv = np.linalg.svd(Fn)
    dd[-1] = 0.0
    Fn = (uu * dd) @ vv
    Fpix = T.T.dot(Fn).dot(T)
    Fpix = Fpix / np.linalg.norm(Fpix)
    return Fpix


def essentialMatrix(F, K1, K2):
    """Essential matrix."""
    Emat = K2.transpose() @ F @ K1
    Emat = Emat / np.linalg.norm(Emat)
    return Emat


def triangulate(C1, pts1, C2, pts2):
    """DLT triangulation."""
    error = 0
    out = []
    for (a, b), (c, d) in zip(pts1, pts2):
        A = np.array([a * C1[2] - C1[0], b * C1[2] - C1[1], c * C2[2] - C2[0], d * C2[2] - C2[1]])
        w = np.linalg.svd(A)[2][-1]
        out.append(w[:3] / w[-1])
    W = np.array(out)
    for C, pts in [(C2, pts2), (C1, pts1)]:
        proj = np.c_[W, np.ones(len(W))] @ C.T
        xy = proj[:, :2] / proj[:, [2]]
        error = error + ((xy - pts) ** 2).sum()
    return W, error
