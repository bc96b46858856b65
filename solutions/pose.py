"""Q3.3: choosing the right camera 2 among the four that E allows."""

from __future__ import annotations

import warnings

import numpy as np

from core.geometry import IDENTITY_POSE, depths
from core.validate import as_matrix, as_points, same_length
from starter import camera2

from .essential import essentialMatrix
from .triangulation import triangulate

__all__ = ["findM2"]


def findM2(F, pts1, pts2, K1, K2):
    """Camera 2's extrinsics: the candidate of ``camera2`` that puts the points in front of both cameras.

    Parameters
    ----------
    F : (3, 3) fundamental matrix, x2^T F x1 = 0 (pixels).
    pts1, pts2 : (N, 2) matching pixels (x, y) = (column, row).
    K1, K2 : (3, 3) intrinsics.  Camera 1 is M1 = [I | 0]: the world frame is camera 1's.

    Returns
    -------
    M2 : (3, 4) [R | t] mapping world (camera-1) coordinates to camera 2; |t| = 1 (E leaves
        the scale free).
    C2 : (3, 4) K2 M2.
    w : (N, 3) the points triangulated with C1 = K1 [I | 0] and C2.

    A RuntimeWarning says when even the chosen candidate leaves most points behind a camera
    (F or the matches are then probably wrong).

    Method (answer key only)
    ------------------------
    The four candidates reproject equally well (a point behind both cameras projects like the
    one in front), so the choice is by cheirality: the most points with positive depth in both
    cameras, ties broken by the smaller reprojection error.
    """
    F = as_matrix(F, "F", (3, 3))
    K1 = as_matrix(K1, "K1", (3, 3))
    K2 = as_matrix(K2, "K2", (3, 3))
    p1 = as_points(pts1, "pts1")
    p2 = as_points(pts2, "pts2")
    n = same_length(pts1=p1, pts2=p2)
    M2s = camera2(essentialMatrix(F, K1, K2))
    C1 = K1 @ IDENTITY_POSE
    best = None
    for i in range(M2s.shape[2]):
        M2 = M2s[:, :, i]
        C2 = K2 @ M2
        w, err = triangulate(C1, p1, C2, p2)
        in_front = int(np.sum((depths(IDENTITY_POSE, w) > 0) & (depths(M2, w) > 0)))
        key = (in_front, -err)
        if best is None or key > best[0]:
            best = (key, M2, C2, w)
    (in_front, _), M2, C2, w = best
    if in_front < n / 2:
        warnings.warn(f"findM2: the best camera leaves {n - in_front} of {n} points behind a camera; "
                      "F or the matches are probably wrong", RuntimeWarning, stacklevel=2)
    return M2, C2, w
