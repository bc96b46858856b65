"""Q3.2, ``triangulate(C1, pts1, C2, pts2) -> (w, err)``: the points and their error.

Every error is recomputed here from the returned points (core.geometry.project): the sum over
the points of |x1 - proj(C1, w)|^2 + |x2 - proj(C2, w)|^2, pixels^2.
"""

from __future__ import annotations

import numpy as np

from core.geometry import project

from .mistakes import error_not_sum_of_squares, points_behind_cameras
from .verdict import Malformed, Verdict, fmt, read_array, read_number, read_parts

__all__ = ["ERR_RTOL", "EXACT_RTOL", "LINEAR_SLACK", "err_reported", "exact_points", "noisy_error", "read_w_err",
           "reprojection_error", "residuals"]

EXACT_RTOL = 1e-6     # noise-free matches: every point within EXACT_RTOL of the scene's size of the truth
LINEAR_SLACK = 1.05   # noisy matches: error at most 5 % above a linear triangulation's (plus 1e-6 px^2 a point)
ERR_RTOL = 1e-4       # err equals the recomputed sum of squares to this relative tolerance

_M1 = np.hstack([np.eye(3), np.zeros((3, 1))])


def read_w_err(value, n: int) -> tuple[np.ndarray, object]:
    """(w (n, 3), err as returned) from a triangulate result, or Malformed."""
    w, err = read_parts(value, 2, "triangulate")
    return read_array(w, (n, 3), "w"), err


def residuals(C1, pts1, C2, pts2, w) -> tuple[np.ndarray, np.ndarray]:
    """x - proj(C, w) in image 1 and image 2, each (N, 2) pixels."""
    return np.asarray(pts1, float) - project(C1, w), np.asarray(pts2, float) - project(C2, w)


def reprojection_error(C1, pts1, C2, pts2, w) -> float:
    """The total squared reprojection error (pixels^2) of w (N, 3) in both images; inf when not finite."""
    r1, r2 = residuals(C1, pts1, C2, pts2, w)
    with np.errstate(all="ignore"):
        total = float(np.sum(r1 ** 2) + np.sum(r2 ** 2))
    return total if np.isfinite(total) else float("inf")


def _scene_size(X) -> float:
    return max(float(np.median(np.linalg.norm(np.asarray(X, float), axis=1))), 1e-12)


def exact_points(w, X, M2=None) -> Verdict:
    """Noise-free matches give the true points X (N, 3): every |w - X| <= EXACT_RTOL * median |X|.

    ``M2`` (3, 4), camera 2's pose, lets the catalogue name points behind a camera.
    """
    what = "noise-free matches give the true 3D points"
    w = np.asarray(w, float)
    with np.errstate(invalid="ignore", over="ignore"):
        gap = float(np.max(np.linalg.norm(w - X, axis=1))) / _scene_size(X) if np.all(np.isfinite(w)) else np.inf
    ok = gap <= EXACT_RTOL
    found = [points_behind_cameras(w, _M1, M2)] if (not ok and M2 is not None and np.all(np.isfinite(w))) else ()
    return Verdict.of(what, ok, f"largest error {fmt(gap)} of the scene's size", f"<= {EXACT_RTOL:g}", found)


def noisy_error(w, C1, pts1, C2, pts2, linear_err: float, M2=None) -> Verdict:
    """On noisy matches, w's error (recomputed) is at most LINEAR_SLACK times a linear triangulation's.

    linear_err : the total squared error of a linear triangulation of the same matches with the
        same cameras (the reference's in the grader, OpenCV's in the public checks); an optimal
        triangulation does better and passes.
    """
    what = "reprojection error as low as a linear triangulation's"
    n = len(np.asarray(pts1))
    total = reprojection_error(C1, pts1, C2, pts2, w)
    goal = LINEAR_SLACK * float(linear_err) + 1e-6 * max(n, 1)
    ok = total <= goal
    found = [points_behind_cameras(w, _M1, M2)] if (not ok and M2 is not None and np.all(np.isfinite(w))) else ()
    return Verdict.of(what, ok, f"{fmt(total)} px^2", f"<= {fmt(goal)} px^2", found)


def err_reported(err, w, C1, pts1, C2, pts2) -> Verdict:
    """err is the total squared reprojection error of the returned w in both images (relative ERR_RTOL)."""
    what = "err is the sum of squared reprojection errors of w"
    r1, r2 = residuals(C1, pts1, C2, pts2, w)
    total = reprojection_error(C1, pts1, C2, pts2, w)
    if not np.isfinite(total):
        return Verdict.of(what, False, "w does not project to finite pixels", "")
    m = error_not_sum_of_squares(err, r1, r2, rtol=ERR_RTOL)
    try:
        shown = fmt(read_number(err, "err"))
    except Malformed:
        shown = "not a number"
    return Verdict.of(what, m is None, f"err = {shown}", f"{fmt(total)} from your w", [m])
