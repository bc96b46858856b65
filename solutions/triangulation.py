"""Q3.2: linear triangulation and its reprojection error."""

from __future__ import annotations

import numpy as np

from core.geometry import project
from core.validate import as_matrix, as_points, same_length

__all__ = ["triangulate"]


def triangulate(C1, pts1, C2, pts2):
    """One 3D point per match of two cameras, and the total reprojection error.

    Parameters
    ----------
    C1, C2 : (3, 4) projection matrices C = K [R | t] of camera 1 and camera 2 (world -> pixels).
    pts1, pts2 : (N, 2) matching pixels (x, y) = (column, row).

    Returns
    -------
    w : (N, 3) world points, one per match.
    err : float
        Total squared reprojection error in pixels^2: the sum over points and both images of
        |x - proj(C, w)|^2, where proj divides by the third homogeneous coordinate.

    Method (answer key only)
    ------------------------
    Each point solves A_i w~_i = 0 with the four rows x C[2] - C[0], y C[2] - C[1] of both
    cameras (each row scaled to unit norm); w~_i is the right singular vector of A_i with
    the smallest singular value, divided by its last coordinate.
    """
    C1 = as_matrix(C1, "C1", (3, 4))
    C2 = as_matrix(C2, "C2", (3, 4))
    p1 = as_points(pts1, "pts1")
    p2 = as_points(pts2, "pts2")
    same_length(pts1=p1, pts2=p2)
    A = np.stack([
        p1[:, :1] * C1[2] - C1[0], p1[:, 1:] * C1[2] - C1[1],
        p2[:, :1] * C2[2] - C2[0], p2[:, 1:] * C2[2] - C2[1],
    ], axis=1)                                   # (N, 4, 4)
    # Rows of very different size (pixels times C) would bias the SVD; unit rows do not.
    A /= np.linalg.norm(A, axis=2, keepdims=True)
    X = np.linalg.svd(A)[2][:, -1, :]            # (N, 4) homogeneous points
    with np.errstate(divide="ignore", invalid="ignore"):
        w = X[:, :3] / X[:, 3:]
    err = float(np.sum((p1 - project(C1, w)) ** 2) + np.sum((p2 - project(C2, w)) ** 2))
    return w, err
