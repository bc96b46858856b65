import numpy as np


def eightpoint(points_a, points_b, scale):
    # scale the coordinates so the system is well conditioned
    norm_mat = np.array([[1.0 / scale, 0, 0], [0, 1.0 / scale, 0], [0, 0, 1]])
    count = points_a.shape[0]
    eqs = []
    for k in range(count):
        xa, ya = points_a[k, 0] / scale, points_a[k, 1] / scale
        xb, yb = points_b[k, 0] / scale, points_b[k, 1] / scale
        eqs.append([xb * xa, xb * ya, xb, yb * xa, yb * ya, yb, xa, ya, 1.0])
    system = np.array(eqs)
    left, sing, right = np.linalg.svd(system)
    f_norm = right[-1].reshape((3, 3))
    # rank 2
    uu, ss, vv = np.linalg.svd(f_norm)
    ss[2] = 0
    f_norm = uu @ np.diag(ss) @ vv
    fund = norm_mat.T @ f_norm @ norm_mat
    return fund / fund[2, 2] if abs(fund[2, 2]) > 1e-12 else fund


def essentialMatrix(F, K1, K2):
    if F.shape != (3, 3):
        raise ValueError("F must be 3x3")
    return np.dot(K2.T, np.dot(F, K1))


def triangulate(C1, pts1, C2, pts2):
    num = len(pts1)
    world = np.zeros((num, 3))
    for j in range(num):
        ua, va = pts1[j]
        ub, vb = pts2[j]
        M = np.vstack([
            va * C1[2, :] - C1[1, :],
            C1[0, :] - ua * C1[2, :],
            vb * C2[2, :] - C2[1, :],
            C2[0, :] - ub * C2[2, :],
        ])
        _, _, v_t = np.linalg.svd(M)
        hom = v_t[-1]
        world[j] = hom[:3] / hom[3]
    world_h = np.hstack((world, np.ones((num, 1))))
    r1 = (C1 @ world_h.T).T
    r2 = (C2 @ world_h.T).T
    r1 = r1[:, :2] / r1[:, 2:3]
    r2 = r2[:, :2] / r2[:, 2:3]
    total = np.sum((r1 - pts1) ** 2) + np.sum((r2 - pts2) ** 2)
    return world, total
