"""Q6: three-view reconstruction of car keypoints, one time step and a whole sequence."""

from __future__ import annotations

import numpy as np
import scipy.optimize

from core.geometry import project
from core.validate import as_finite_scalar, as_matrix, as_points, same_length

__all__ = ["MultiviewReconstruction", "plot_3d_keypoint_video"]


def _dlt(Cs, xy):
    """One point from V >= 2 views: Cs (V, 3, 4), xy (V, 2) pixels -> (3,) world point."""
    A = np.concatenate([xy[:, :1] * Cs[:, 2] - Cs[:, 0], xy[:, 1:] * Cs[:, 2] - Cs[:, 1]])
    X = np.linalg.svd(A)[2][-1]
    return X[:3] / X[3]


def MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres):
    """3D keypoints from three views, using only detections more confident than ``Thres``.

    Parameters
    ----------
    C1, C2, C3 : (3, 4) projection matrices K [R | t] (world -> pixels) of the three cameras.
    pts1, pts2, pts3 : (N, 3) detections [x, y, confidence]: pixels (x = column, y = row) and a
        confidence (larger is more reliable).
    Thres : a detection is used when its confidence is strictly greater than Thres.

    Returns
    -------
    P : (N, 3) world points; a keypoint seen confidently in fewer than two views is NaN.
    err : total squared reprojection error (pixels^2) over the detections used.

    Method (answer key only)
    ------------------------
    Each keypoint is first triangulated linearly (DLT) from the two or three views that pass the
    threshold, then refined by least squares on its reprojection error in those views.
    """
    Cs = np.stack([as_matrix(C, f"C{i}", (3, 4)) for i, C in enumerate((C1, C2, C3), 1)])
    pts = [as_points(p, f"pts{i}", dims=3) for i, p in enumerate((pts1, pts2, pts3), 1)]
    n = same_length(pts1=pts[0], pts2=pts[1], pts3=pts[2])
    thres = as_finite_scalar(Thres, "Thres")
    xy = np.stack([p[:, :2] for p in pts], axis=1)            # (N, 3 views, 2)
    used = np.stack([p[:, 2] > thres for p in pts], axis=1)    # (N, 3)
    P = np.full((n, 3), np.nan)
    err = 0.0
    for i in range(n):
        v = np.flatnonzero(used[i])
        if v.size < 2:
            continue
        views, seen = Cs[v], xy[i, v]
        P0 = _dlt(views, seen)
        fit = scipy.optimize.least_squares(
            lambda X: (np.concatenate([project(C, X) for C in views]) - seen).ravel(), P0, method="lm")
        P[i] = fit.x
        err += float(np.sum(fit.fun ** 2))
    return P, err


def plot_3d_keypoint_video(pts_3d_video):
    """One 3D figure of the car at every time step, one colour per step.

    Parameters
    ----------
    pts_3d_video : (T, 12, 3) array (or a list of T arrays (12, 3)) of world keypoints; NaN rows
        (keypoints not reconstructed) are left out of the drawing.

    Returns
    -------
    A ``starter.Figure3D`` (rotatable on screen, with a static image for the PDF).
    """
    from starter import plot_3d_keypoint_frames

    video = np.asarray([np.asarray(p, dtype=float) for p in pts_3d_video])
    if video.ndim != 3 or video.shape[2] != 3:
        raise ValueError(f"pts_3d_video: expected shape (T, N, 3), got {video.shape}")
    return plot_3d_keypoint_frames(video, title=f"the car over {len(video)} time steps")
