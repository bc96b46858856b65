import numpy as np


def _centroid_normaliser(pts):
    mean = np.mean(pts, axis=0)
    dist = np.sqrt(np.sum((pts - mean) ** 2, axis=1)).mean()
    s = np.sqrt(2.0) / dist
    return np.array([[s, 0.0, -s * mean[0]], [0.0, s, -s * mean[1]], [0.0, 0.0, 1.0]])


def eightpoint(pts1, pts2, M):
    pts1 = pts1.astype(float)
    pts2 = pts2.astype(float)
    T1 = _centroid_normaliser(pts1)
    T2 = _centroid_normaliser(pts2)
    a = (T1 @ np.vstack([pts1.T, np.ones(len(pts1))])).T
    b = (T2 @ np.vstack([pts2.T, np.ones(len(pts2))])).T
    A = np.ones((len(a), 9))
    for j in range(3):
        for i in range(3):
            A[:, 3 * j + i] = b[:, j] * a[:, i]
    _, _, V = np.linalg.svd(A, full_matrices=False)
    G = np.reshape(V[8], (3, 3))
    u, d, v = np.linalg.svd(G)
    G = u @ np.diag(np.array([d[0], d[1], 0.0])) @ v
    F = np.transpose(T2) @ G @ T1
    return F / np.sqrt(np.sum(F ** 2))


def essentialMatrix(F, K1, K2):
    assert F.shape == (3, 3) and K1.shape == (3, 3) and K2.shape == (3, 3)
    left = K2.T
    E = left @ F
    E = E @ K1
    return E


def triangulate(C1, pts1, C2, pts2):
    def rows(C, x, y):
        return [x * C[2] - C[0], y * C[2] - C[1]]

    pts = []
    for (xa, ya), (xb, yb) in zip(pts1, pts2):
        A = np.array(rows(C1, xa, ya) + rows(C2, xb, yb))
        A = A / np.linalg.norm(A, axis=1, keepdims=True)
        vec = np.linalg.svd(A)[-1][-1]
        pts.append(vec[:-1] / vec[-1])
    pts = np.array(pts)
    hom = np.concatenate([pts, np.ones((len(pts), 1))], axis=1)
    err = 0.0
    for C, obs in zip((C1, C2), (pts1, pts2)):
        z = hom @ C.T
        err += np.sum(np.square(obs - z[:, :2] / z[:, 2, None]))
    return pts, err
