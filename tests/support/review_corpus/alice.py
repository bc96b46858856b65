import numpy as np


def eightpoint(pts1, pts2, M):
    # scale the coordinates so the system is well conditioned
    T = np.array([[1.0 / M, 0, 0], [0, 1.0 / M, 0], [0, 0, 1]])
    n = pts1.shape[0]
    rows = []
    for i in range(n):
        u1, v1 = pts1[i, 0] / M, pts1[i, 1] / M
        u2, v2 = pts2[i, 0] / M, pts2[i, 1] / M
        rows.append([u2 * u1, u2 * v1, u2, v2 * u1, v2 * v1, v2, u1, v1, 1.0])
    A = np.array(rows)
    U, S, Vh = np.linalg.svd(A)
    Fs = Vh[-1].reshape((3, 3))
    # rank 2
    u, s, vh = np.linalg.svd(Fs)
    s[2] = 0
    Fs = u @ np.diag(s) @ vh
    F = T.T @ Fs @ T
    return F / F[2, 2] if abs(F[2, 2]) > 1e-12 else F


def essentialMatrix(F, K1, K2):
    if F.shape != (3, 3):
        raise ValueError("F must be 3x3")
    return np.dot(K2.T, np.dot(F, K1))


def triangulate(C1, pts1, C2, pts2):
    n = len(pts1)
    P = np.zeros((n, 3))
    for i in range(n):
        x1, y1 = pts1[i]
        x2, y2 = pts2[i]
        A = np.vstack([
            y1 * C1[2, :] - C1[1, :],
            C1[0, :] - x1 * C1[2, :],
            y2 * C2[2, :] - C2[1, :],
            C2[0, :] - x2 * C2[2, :],
        ])
        _, _, vt = np.linalg.svd(A)
        X = vt[-1]
        P[i] = X[:3] / X[3]
    Ph = np.hstack((P, np.ones((n, 1))))
    proj1 = (C1 @ Ph.T).T
    proj2 = (C2 @ Ph.T).T
    proj1 = proj1[:, :2] / proj1[:, 2:3]
    proj2 = proj2[:, :2] / proj2[:, 2:3]
    err = np.sum((proj1 - pts1) ** 2) + np.sum((proj2 - pts2) ** 2)
    return P, err
