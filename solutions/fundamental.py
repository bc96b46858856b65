"""Q2: the eight-point algorithm."""

from __future__ import annotations

import numpy as np

from starter import refineF
from starter.epipolar import enforce_rank2
from core.validate import DegenerateInputError, as_points, as_positive_scalar, same_length

__all__ = ["eightpoint"]


def eightpoint(pts1, pts2, M, *, refine=True):
    """Fundamental matrix from N >= 8 matches by the eight-point algorithm, with coordinates scaled by 1/M.

    Parameters
    ----------
    pts1, pts2 : (N, 2) array
        Matching pixels (x, y) = (column, row) in image 1 and image 2, N >= 8.  Integer arrays
        (the data files are uint16) are cast to float first, so nothing wraps around.
    M : float
        Scale: the larger of the image's width and height.  As the handout says, every
        coordinate is divided by M before the linear solve, and F is unscaled afterwards.

    Returns
    -------
    F : (3, 3) array
        Rank 2 (the handout asks for the singularity condition to be enforced before unscaling),
        in pixels: x2^T F x1 = 0, so F maps a point of image 1 to its epipolar line in image 2.
        F is defined up to scale and sign.  The handout suggests calling the given
        ``refineF(F, pts1, pts2)`` from here, before unscaling; it is optional.

    Raises
    ------
    ValueError
        For wrong shapes, fewer than 8 points, NaN/inf, or a non-positive M.
    DegenerateInputError
        When the matches do not pin F down (e.g. fewer than 8 distinct or collinear points).

    Method (answer key only)
    ------------------------
    One row per match, linear in the nine entries of F; the right singular vector of the
    smallest singular value, then the closest rank-2 matrix; refineF on the scaled F and
    points; unscale with T = diag(1/M, 1/M, 1) as T^T F T; unit Frobenius norm.

    refine : keyword only, not the handout's
        False skips refineF.  Only the kit's own code (tests, the grader's reference variants,
        ``kit run``) passes it; the students' function has the handout's three arguments.
    """
    p1 = as_points(pts1, "pts1", min_count=8) / as_positive_scalar(M, "M")
    p2 = as_points(pts2, "pts2", min_count=8) / M
    same_length(pts1=p1, pts2=p2)
    x1, y1 = p1.T
    x2, y2 = p2.T
    # One row per match: x2^T F x1 = 0 is linear in the entries of F (row-major).
    A = np.stack([x2 * x1, x2 * y1, x2, y2 * x1, y2 * y1, y2, x1, y1, np.ones_like(x1)], axis=1)
    _, S, Vt = np.linalg.svd(A)
    if S[7] <= 1e-12 * S[0]:
        raise DegenerateInputError(
            "pts1, pts2: the matches leave F undetermined (the 8-point system has rank "
            f"{int(np.sum(S > 1e-12 * S[0]))} < 8: repeated, collinear or too few distinct points)")
    F = enforce_rank2(Vt[-1].reshape(3, 3))
    if refine:
        F = refineF(F, p1, p2)
    T = np.diag([1.0 / M, 1.0 / M, 1.0])
    F = T.T @ F @ T
    return F / np.linalg.norm(F)
