import numpy as np


def eightpoint(pts1, pts2, M):
    """Normalised 8-point."""
    N = len(pts1)
    T = np.diag([1 / M, 1 / M, 1])
    h1 = np.column_stack([pts1, np.ones(N)]) @ T.T
    h2 = np.column_stack([pts2, np.ones(N)]) @ T.T
    A = np.column_stack([h2[:, 0:1] * h1, h2[:, 1:2] * h1, h1])
    f = np.linalg.svd(A.T @ A)[2][-1]
    Fn = f.reshape(3, 3)
    uu, dd, vv = np.linalg.svd(Fn)
    dd[-1] = 0.0
    Fn = (uu * dd) @ vv
    F = T.T.dot(Fn).dot(T)
    F = F / np.linalg.norm(F)
    return F


def essentialMatrix(F, K1, K2):
    """Essential matrix."""
    E = K2.transpose() @ F @ K1
    E = E / np.linalg.norm(E)
    return E


def triangulate(C1, pts1, C2, pts2):
    """DLT triangulation."""
    out = []
    for (a, b), (c, d) in zip(pts1, pts2):
        A = np.array([a * C1[2] - C1[0], b * C1[2] - C1[1], c * C2[2] - C2[0], d * C2[2] - C2[1]])
        w = np.linalg.svd(A)[2][-1]
        out.append(w[:3] / w[-1])
    W = np.array(out)
    error = 0
    for C, pts in [(C1, pts1), (C2, pts2)]:
        proj = np.c_[W, np.ones(len(W))] @ C.T
        xy = proj[:, :2] / proj[:, [2]]
        error = error + ((xy - pts) ** 2).sum()
    return W, error
