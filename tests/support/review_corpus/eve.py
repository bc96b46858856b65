import numpy as np


def eightpoint(pts1, pts2, M):
    x = np.array(pts1, float) / M
    xp = np.array(pts2, float) / M
    n = x.shape[0]
    A = np.empty((n, 9))
    A[:, 0] = xp[:, 0] * x[:, 0]
    A[:, 1] = xp[:, 0] * x[:, 1]
    A[:, 2] = xp[:, 0]
    A[:, 3] = xp[:, 1] * x[:, 0]
    A[:, 4] = xp[:, 1] * x[:, 1]
    A[:, 5] = xp[:, 1]
    A[:, 6] = x[:, 0]
    A[:, 7] = x[:, 1]
    A[:, 8] = 1
    sol = np.linalg.svd(A)[2][8, :]
    Fhat = np.reshape(sol, (3, 3))
    w, s, vt = np.linalg.svd(Fhat)
    Fhat = w @ np.diag([*s[:2], 0]) @ vt
    Tm = np.diag([1.0 / M, 1.0 / M, 1.0])
    return Tm @ Fhat @ Tm


def essentialMatrix(F, K1, K2):
    return (K1.T @ F.T @ K2).T


def triangulate(C1, pts1, C2, pts2):
    def eqs(P, u, v):
        return [u * P[2] - P[0], v * P[2] - P[1]]

    out = []
    for (u1, v1), (u2, v2) in zip(pts1, pts2):
        S = np.array(eqs(C1, u1, v1) + eqs(C2, u2, v2))
        S = S / np.linalg.norm(S, axis=1, keepdims=True)
        h = np.linalg.svd(S)[-1][-1]
        out.append(h[:-1] / h[-1])
    out = np.array(out)
    homog = np.concatenate([out, np.ones((len(out), 1))], axis=1)
    total = 0.0
    for P, seen in zip((C1, C2), (pts1, pts2)):
        z = homog @ P.T
        total += np.sum(np.square(seen - z[:, :2] / z[:, 2, None]))
    return out, total
