import numpy as np


def eightpoint(pts1, pts2, M):
    p = np.asarray(pts1, dtype=np.float64) / M
    q = np.asarray(pts2, dtype=np.float64) / M
    ones = np.ones((p.shape[0], 1))
    ph = np.hstack([p, ones])
    qh = np.hstack([q, ones])
    A = np.stack([np.kron(qh[i], ph[i]) for i in range(len(p))])
    eigvals, eigvecs = np.linalg.eigh(A.T @ A)
    F = eigvecs[:, np.argmin(eigvals)].reshape(3, 3)
    U, sig, Vt = np.linalg.svd(F)
    F = U @ np.diag([sig[0], sig[1], 0]) @ Vt
    scale = np.diag([1 / M, 1 / M, 1])
    return np.matmul(scale.T, np.matmul(F, scale))


def essentialMatrix(F, K1, K2):
    F = np.asarray(F, dtype=float)
    K1 = np.asarray(K1, dtype=float)
    K2 = np.asarray(K2, dtype=float)
    return np.matmul(np.matmul(np.transpose(K2), F), K1)


def triangulate(C1, pts1, C2, pts2):
    pts1 = np.asarray(pts1, float)
    pts2 = np.asarray(pts2, float)
    P = np.empty((len(pts1), 3))
    for k in range(len(pts1)):
        A = np.zeros((4, 3))
        b = np.zeros(4)
        for r, (C, (x, y)) in enumerate([(C1, pts1[k]), (C2, pts2[k])]):
            A[2 * r] = x * C[2, :3] - C[0, :3]
            A[2 * r + 1] = y * C[2, :3] - C[1, :3]
            b[2 * r] = C[0, 3] - x * C[2, 3]
            b[2 * r + 1] = C[1, 3] - y * C[2, 3]
        P[k] = np.linalg.lstsq(A, b, rcond=None)[0]
    err = 0.0
    for C, pts in ((C1, pts1), (C2, pts2)):
        proj = P @ C[:, :3].T + C[:, 3]
        d = pts - proj[:, :2] / proj[:, 2:]
        err += float(np.einsum("ij,ij->", d, d))
    return P, err
