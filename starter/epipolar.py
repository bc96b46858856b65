"""Epipolar geometry helpers given to students: distances to epipolar lines and ``refineF``.

Conventions: points are pixels (x, y) = (column, row), arrays of shape (N, 2); F (3x3) maps a
point x1 of image 1 to the line l2 = F x1 in image 2, so that x2^T F x1 = 0 for a true match.
"""

from __future__ import annotations

import numpy as np

from core import geometry, refine_switch
from core.geometry import enforce_rank2
from core.validate import as_matrix, as_points, same_length

__all__ = ["enforce_rank2", "epipolar_distances", "symmetric_epipolar_cost", "refineF"]


def epipolar_distances(F, pts1, pts2) -> np.ndarray:
    """Distance in pixels (N,) of each x2 to its epipolar line F x1 in image 2.

    Parameters
    ----------
    F : (3, 3) fundamental matrix, x2^T F x1 = 0.
    pts1, pts2 : (N, 2) pixels (x, y) of matched points in image 1 and image 2.

    Returns
    -------
    (N,) distances in pixels; inf where the line F x1 is undefined (F x1 has no direction).

    The arguments are checked here (ValueError naming the bad one); the distance itself is
    core.geometry.epipolar_distances.
    """
    F = as_matrix(F, "F", (3, 3))
    p1 = as_points(pts1, "pts1")
    p2 = as_points(pts2, "pts2")
    same_length(pts1=p1, pts2=p2)
    return geometry.epipolar_distances(F, p1, p2)


def symmetric_epipolar_cost(F: np.ndarray, pts1: np.ndarray, pts2: np.ndarray) -> float:
    """Sum over points of the squared distances of x2 to F x1 plus of x1 to F^T x2 (pixels^2).

    F (3, 3); pts1, pts2 (N, 2) float points, not checked (this runs inside the optimiser).
    This is the geometric cost ``refineF`` minimises; inf when a line is undefined.
    """
    return geometry.symmetric_epipolar_cost_of(pts1, pts2)(np.asarray(F, float))


def refineF(F, pts1, pts2) -> np.ndarray:
    """Locally refine a fundamental matrix; return the rank-2 result (3x3).

    Starting from ``F``, Powell's method (scipy.optimize.minimize) minimises the symmetric
    epipolar distance of the matches, rank 2 being enforced inside the cost.  Call it from
    ``eightpoint`` *before* unscaling, with the points divided by M: the cost is then well
    conditioned.  It improves a good F; it does not rescue a wrong one.

    Parameters
    ----------
    F : (3, 3) initial fundamental matrix (x2^T F x1 = 0) in the coordinates of pts1/pts2, or
        its 9 entries in any shape (read row by row, as ``F.reshape(3, 3)``).
    pts1, pts2 : (N, 2) matched points (x, y) in those same coordinates, N >= 8.

    Returns
    -------
    (3, 3) rank-2 fundamental matrix in the same coordinates, scaled to unit Frobenius norm.

    While the self-check or the grader switches refineF off (``core.refine_switch``, the FAQ's
    "comment out refineF"), the arguments are checked the same way and the minimisation alone
    is skipped: the result is then the closest rank-2 matrix to F, scaled to unit norm.
    """
    F = refine_switch.as_F(F)
    p1 = as_points(pts1, "pts1", min_count=8)
    p2 = as_points(pts2, "pts2", min_count=8)
    same_length(pts1=p1, pts2=p2)
    grader = refine_switch.grader_helper()
    if grader is not None:
        # Inside the grader's sandbox the grader computes it (switched off or not, as it decided):
        # nothing the code under test changes in this process can bring the minimisation back.
        refine_switch.count_call()
        return grader(F, p1, p2)
    if refine_switch.is_off():
        return refine_switch.polish_skipped(F)
    from starter.refine_polish import polish   # not shipped to the sandbox: see the branch above

    return polish(F, p1, p2)
