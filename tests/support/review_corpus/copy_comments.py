import numpy as np

# Q2: the eight point algorithm
def eightpoint(pts1,pts2,M):
    """Returns the fundamental matrix F (3x3) such that x2^T F x1 = 0."""
    # normalise the points
    p = np.asarray(pts1, dtype = np.float64)/M
    q = np.asarray(pts2, dtype = np.float64)/M

    ones = np.ones((p.shape[0],1))
    ph = np.hstack([p,ones])   # homogeneous
    qh = np.hstack([q,ones])

    # each row is kron(x2, x1)
    A = np.stack(
        [np.kron(qh[i], ph[i])
         for i in range(len(p))]
    )
    # smallest eigenvector of A^T A
    eigvals, eigvecs = np.linalg.eigh(A.T@A)
    F = eigvecs[:, np.argmin(eigvals)].reshape(3,3)

    # enforce rank 2
    U, sig, Vt = np.linalg.svd(F)
    F = U@np.diag([sig[0], sig[1], 0])@Vt

    # unscale
    scale = np.diag([1/M, 1/M, 1])
    return np.matmul(scale.T,
                     np.matmul(F, scale))


# Q3.1
def essentialMatrix(F, K1, K2):
    """E = K2' F K1"""
    F = np.asarray(F, dtype=float)    # make sure
    K1 = np.asarray(K1, dtype=float)
    K2 = np.asarray(K2, dtype=float)

    return np.matmul(np.matmul(np.transpose(K2), F), K1)


# Q3.2
def triangulate(C1, pts1, C2, pts2):
    """Least squares triangulation; returns the points and the total reprojection error."""
    pts1 = np.asarray(pts1, float)
    pts2 = np.asarray(pts2, float)
    P = np.empty((len(pts1), 3))

    for k in range(len(pts1)):
        A = np.zeros((4, 3)); b = np.zeros(4)
        for r, (C, (x, y)) in enumerate([(C1, pts1[k]), (C2, pts2[k])]):
            # two rows per camera
            A[2*r] = x*C[2, :3] - C[0, :3]
            A[2*r+1] = y*C[2, :3] - C[1, :3]
            b[2*r] = C[0, 3] - x*C[2, 3]
            b[2*r+1] = C[1, 3] - y*C[2, 3]
        P[k] = np.linalg.lstsq(A, b, rcond=None)[0]

    # reprojection error, summed over both images
    err = 0.0
    for C, pts in ((C1, pts1), (C2, pts2)):
        proj = P@C[:, :3].T + C[:, 3]
        d = pts - proj[:, :2]/proj[:, 2:]
        err += float(np.einsum("ij,ij->", d, d))
    return P, err
