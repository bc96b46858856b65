import numpy as np
from starter import refineF
from starter.epipolar import enforce_rank2
from core.validate import DegenerateInputError, as_points, as_positive_scalar, same_length


def eightpoint(pts1, pts2, M, refine=True):
    """My eight point algorithm."""
    a = as_points(pts1, "pts1", min_count=8) / as_positive_scalar(M, "M")
    b = as_points(pts2, "pts2", min_count=8) / M
    same_length(pts1=a, pts2=b)
    u2, v2 = b.T   # second image
    u1, v1 = a.T   # first image
    # build the linear system
    system = np.stack([u2 * u1, u2 * v1, u2, v2 * u1, v2 * v1, v2, u1, v1, np.ones_like(u1)], axis=1)
    _, sv, right = np.linalg.svd(system)
    if sv[7] <= 1e-12 * sv[0]:
        raise DegenerateInputError(
            "degenerate points: rank "
            f"{int(np.sum(sv > 1e-12 * sv[0]))} < 8")
    scaling = np.diag([1.0 / M, 1.0 / M, 1.0])
    fund = enforce_rank2(right[-1].reshape(3, 3))
    if refine:
        fund = refineF(fund, a, b)
    fund = scaling.T @ fund @ scaling
    return fund / np.linalg.norm(fund)
