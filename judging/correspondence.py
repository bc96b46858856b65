"""Q4.1 ``epipolarCorrespondence`` and Q4.2 ``compute3D_pts``: matches and 3D points near the truth.

A match is right within ``tolerance(width)`` pixels of the true match; a 3D point is right when it
reprojects (core.geometry.project) within that tolerance of the point in image 1 and of its true
match in image 2.  The goal is a share of the points: 70 % of what a reference matcher reaches on
the same points (``ref_share``; 1 when there is none), partial credit down to 20 % of it.
"""

from __future__ import annotations

import numpy as np

from core.geometry import project

from .mistakes import points_behind_cameras, points_xy_swapped
from .triangulation import LINEAR_SLACK, reprojection_error
from .verdict import Malformed, Verdict, fmt, read_array, read_number, share_score

__all__ = ["FLOOR", "GOAL", "PTS2_SHARE", "matches", "points3d", "pts2_reported", "read_match", "read_points",
           "read_points_pts2", "right_2d", "right_3d", "tolerance"]

GOAL, FLOOR = 0.7, 0.2
PTS2_SHARE = 0.9   # share of the points whose w must reproject onto the pts1 and pts2 returned with it
_M1 = np.hstack([np.eye(3), np.zeros((3, 1))])


def tolerance(width: float) -> float:
    """Pixels within which a match counts as right, for images ``width`` pixels wide (3 px at 640)."""
    return max(2.0, 3.0 * float(width) / 640.0)


def read_match(value) -> np.ndarray:
    """(x2, y2) as a float array (2,) from one epipolarCorrespondence result, or Malformed."""
    if isinstance(value, (tuple, list)) and len(value) == 2:
        return np.array([read_number(v, "x2" if k == 0 else "y2") for k, v in enumerate(value)])
    return read_array(value, (2,), "(x2, y2)")


def read_points(value, n: int) -> np.ndarray:
    """w (n, 3) from compute3D_pts's result: w alone, or a tuple starting with w; or Malformed."""
    if isinstance(value, (tuple, list)) and len(value) in (2, 3):
        value = value[0]
    return read_array(value, (n, 3), "the 3D points")


def read_points_pts2(value, n: int) -> tuple[np.ndarray, object]:
    """(w (n, 3), pts2 as returned or None) from compute3D_pts's result ((w, pts2), or w alone); or Malformed."""
    pts2 = value[1] if isinstance(value, (tuple, list)) and len(value) in (2, 3) else None
    return read_points(value, n), pts2


def pts2_reported(pts2, w, C1, pts1, C2, tol: float, linear_error=None) -> Verdict:
    """pts2 (N, 2), returned with w (N, 3), are the matches w was triangulated from.

    Passed when w reprojects within ``tol`` px of pts1 (N, 2) through C1 and of pts2 through C2
    (:func:`right_3d`) for a share >= PTS2_SHARE of the points, or, for matches off their epipolar
    lines (which no point reprojects onto), when w's total squared reprojection error on (pts1,
    pts2) is at most LINEAR_SLACK times that of a linear triangulation of them, ``linear_error(C1,
    pts1, C2, pts2) -> float`` (the reference's in the grader; None: not tried).  Names
    points_xy_swapped when pts2 holds (y, x).
    """
    what = "pts2 are the matches w was triangulated from"
    w = np.asarray(w, float)
    try:
        pts2 = read_array(pts2, (len(w), 2), "pts2")
    except Malformed as exc:
        return Verdict.failed(what, str(exc))
    right = right_3d(w, C1, C2, pts1, pts2, tol)
    share = float(right.mean()) if len(right) else 0.0
    ok = share >= PTS2_SHARE
    lines = []
    if not ok and linear_error is not None and np.all(np.isfinite(pts2)):
        err, goal = reprojection_error(C1, pts1, C2, pts2, w), LINEAR_SLACK * float(linear_error(C1, pts1, C2, pts2))
        ok = err <= goal + 1e-6 * max(len(w), 1)
        lines.append(f"reprojection error of w on pts1 and your pts2: {fmt(err)} px^2 (a linear triangulation "
                     f"of them: {fmt(goal / LINEAR_SLACK)} px^2)")
    swapped = None
    if not ok and np.all(np.isfinite(w)):
        with np.errstate(all="ignore"):
            swapped = points_xy_swapped(np.nan_to_num(pts2, nan=-1e9), project(C2, w), tol)
    return Verdict.of(what, ok, f"{int(right.sum())} of {len(right)} of your points reproject within {tol:g} px "
                                f"of pts1 and of your pts2", f">= {PTS2_SHARE:.0%}", [swapped], lines)


def _goal(share: float, ref_share: float, tol: float, n_right: int, n: int, what: str, mistakes=()) -> Verdict:
    goal, floor = GOAL * ref_share, FLOOR * ref_share
    return Verdict(what, share >= goal, share_score(share, goal, floor), f"{n_right} of {n} within {tol:g} px",
                   f">= {goal:.0%}", (), tuple(m for m in mistakes if m is not None))


def right_2d(pts2, truth2, tol: float) -> np.ndarray:
    """(P,) bool: the matches pts2 (P, 2) within ``tol`` px of truth2 (P, 2) (NaN is never right)."""
    d = np.linalg.norm(np.asarray(pts2, float) - truth2, axis=1)
    return np.where(np.isfinite(d), d, np.inf) <= tol


def matches(pts2, truth2, tol: float, ref_share: float = 1.0) -> Verdict:
    """pts2 (P, 2), the matches found, within ``tol`` px of truth2 (P, 2) for a share >= GOAL * ref_share."""
    what = "matches near the true ones"
    pts2 = np.asarray(pts2, float)
    right = right_2d(pts2, truth2, tol)
    share = float(right.mean()) if len(right) else 0.0
    swapped = None if share >= GOAL * ref_share else points_xy_swapped(np.nan_to_num(pts2, nan=-1e9), truth2, tol)
    return _goal(share, ref_share, tol, int(right.sum()), len(right), what, [swapped])


def right_3d(w, C1, C2, pts1, truth2, tol: float) -> np.ndarray:
    """(P,) bool: w (P, 3) reprojects within tol of pts1 (P, 2) through C1 and of truth2 (P, 2) through C2."""
    d1 = np.linalg.norm(project(C1, w) - pts1, axis=1)
    d2 = np.linalg.norm(project(C2, w) - truth2, axis=1)
    d1, d2 = (np.where(np.isfinite(d), d, np.inf) for d in (d1, d2))
    return (d1 <= tol) & (d2 <= tol)


def points3d(w, C1, C2, pts1, truth2, tol: float, ref_share: float = 1.0, M2=None) -> Verdict:
    """3D points w (P, 3) right (see :func:`right_3d`) for a share >= GOAL * ref_share.

    ``M2`` (3, 4), camera 2's pose when known, lets the catalogue name points behind a camera.
    """
    what = "3D points near the true ones"
    w = np.asarray(w, float)
    right = right_3d(w, C1, C2, pts1, truth2, tol)
    share = float(right.mean()) if len(right) else 0.0
    behind = None
    if M2 is not None and share < GOAL * ref_share and np.all(np.isfinite(w)):
        behind = points_behind_cameras(w, _M1, M2)
    return _goal(share, ref_share, tol, int(right.sum()), len(right), what, [behind])
