"""Q4.1 ``epipolarCorrespondence`` and Q4.2 ``compute3D_pts``: matches and 3D structure near the truth.

The points judged are the *easy* ones of a scene (the handout: "it should get easy points (such
as those with distinctive, corner-like windows)"), chosen grader-side where their window is
distinctive along the true epipolar line.  A match is right within ``tolerance(width)`` pixels of
the true match.  A 3D point is right when, after the reconstruction is moved onto the true points
by the similarity that fits it best (its gauge: the cameras may come from the student's own
findM2, |t| = 1), it lies within ``tol3d`` of its true point on the surface, ``tol3d`` being how
far a match ``tolerance`` px off along its epipolar line moves the point (:func:`right_structure`).

The goal is a share of the points: 70 % of ``ref_share``, what the weakest of several correct
matcher styles reaches on those very points (1 when unknown), and never fewer than MIN_RIGHT
points; partial credit down to 20 % of it.
"""

from __future__ import annotations

import numpy as np

from core.geometry import project, similarity_fit

from .mistakes import points_behind_cameras, points_xy_swapped
from .triangulation import LINEAR_SLACK, reprojection_error
from .verdict import Malformed, Verdict, fmt, read_array, read_number, share_score

__all__ = ["FLOOR", "GOAL", "MIN_RIGHT", "PTS2_SHARE", "matches", "points3d", "pts2_reported", "read_match",
           "read_points", "read_points_pts2", "right_2d", "right_3d", "right_structure", "structure_goal", "tolerance"]

GOAL, FLOOR = 0.7, 0.2
MIN_RIGHT = 2      # the goal never asks fewer points than this (nor more than there are)
_SHOWN = 3         # the wrong points whose distances the feedback lists
_SAMPLES = 60      # triples right_structure fits from
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


def _shape(v):
    try:
        return np.shape(v)
    except (TypeError, ValueError):
        return None


def _points_shape(shape, n: int) -> bool:
    """True for the shape of n 3D points: (n, 3), or homogeneous (n, 4)."""
    return shape in ((n, 3), (n, 4))


def _dehomogenised(value, n: int) -> np.ndarray:
    """w (n, 3) from n points (n, 3), or homogeneous (n, 4) (divided by their last column: a point
    whose last entry is 0 is at infinity, not finite, so never right); or Malformed."""
    if _shape(value) == (n, 4):
        wh = read_array(value, (n, 4), "the 3D points")
        with np.errstate(all="ignore"):
            return wh[:, :3] / wh[:, 3:]
    return read_array(value, (n, 3), "the 3D points")


def read_points(value, n: int) -> np.ndarray:
    """w (n, 3) from compute3D_pts's result, or Malformed.

    Accepted: w alone; a tuple or list starting with w ((w, pts2), (w, err)); or, as 2022-2024
    hand-ins return it, a tuple holding w among 3 x 4 matrices ((M2, C2, P), (M2, C2, P, M1, C1)):
    the one element of shape (n, 3).  w may be homogeneous (n, 4), as triangulate's SVD gives
    it: divided by its last column.  A 3 x 4 matrix alone (M2 or C2) is Malformed, saying so.
    """
    if isinstance(value, (tuple, list)) and value and not np.isscalar(value[0]):
        shapes = [_shape(v) for v in value]
        if not _points_shape(shapes[0], n) and all(sh is not None and len(sh) == 2 for sh in shapes):
            found = [v for v, sh in zip(value, shapes) if _points_shape(sh, n)]
            if len(found) == 1:
                return _dehomogenised(found[0], n)
        if len(value) in (2, 3) or _points_shape(shapes[0], n):
            value = value[0]
    if _shape(value) == (3, 4) and n not in (3, 4):
        raise Malformed(f"expected the {n} x 3 points, got a 3 x 4 matrix (a camera such as M2 or C2?)")
    return _dehomogenised(value, n)


def read_points_pts2(value, n: int) -> tuple[np.ndarray, object]:
    """(w (n, 3), pts2 as returned or None) from compute3D_pts's result ((w, pts2), or w alone); or Malformed."""
    pts2 = value[1] if isinstance(value, (tuple, list)) and len(value) == 2 and _shape(value[1]) == (n, 2) else None
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


def structure_goal(ref_share: float, n: int, flat_share: float = 0.0) -> float:
    """Q4.2's share worth full marks: :func:`goal_share`, and at least halfway from what a flat
    temple reaches (``flat_share``: solutions.matching_styles.EasyProblem.flat_share_3d) to every
    point, since the handout asks for the temple's 3D structure to be evident, and up to a
    similarity a plane lies near many points where the relief is small."""
    return max(goal_share(ref_share, n), flat_share + (1.0 - flat_share) / 2 if flat_share > 0 else 0.0)


def goal_share(ref_share: float, n: int) -> float:
    """The share of n points worth full marks: GOAL * ref_share, at least MIN_RIGHT points (at most all)."""
    return min(1.0, max(GOAL * ref_share, MIN_RIGHT / max(n, 1)))


def _goal(share: float, ref_share: float, within: str, n_right: int, n: int, what: str, mistakes=(),
          lines=(), goal: float | None = None) -> Verdict:
    goal = goal_share(ref_share, n) if goal is None else goal
    floor = goal * FLOOR / GOAL
    return Verdict(what, share >= goal, share_score(share, goal, floor), f"{n_right} of {n} {within}",
                   f">= {goal:.0%}", tuple(lines), tuple(m for m in mistakes if m is not None))


def _where(pts1, dist, right, unit: str) -> list[str]:
    """A line naming how far the first few wrong points are off (pts1 (P, 2) or None, dist (P,))."""
    wrong = np.flatnonzero(~right)[:_SHOWN]
    if not len(wrong):
        return []
    parts = []
    for k in wrong:
        at = "" if pts1 is None else f"({pts1[k][0]:g}, {pts1[k][1]:g}): "
        parts.append(at + ("no result" if not np.isfinite(dist[k]) else f"{dist[k]:.1f} {unit} off"))
    return [f"{int((~right).sum())} not right; the first {len(wrong)}: " + "; ".join(parts)]


def right_2d(pts2, truth2, tol: float) -> np.ndarray:
    """(P,) bool: the matches pts2 (P, 2) within ``tol`` px of truth2 (P, 2) (NaN is never right)."""
    d = np.linalg.norm(np.asarray(pts2, float) - truth2, axis=1)
    return np.where(np.isfinite(d), d, np.inf) <= tol


def matches(pts2, truth2, tol: float, ref_share: float = 1.0, pts1=None) -> Verdict:
    """pts2 (P, 2), the matches found of the easy points pts1 (P, 2) (only named in the feedback;
    None: not named), within ``tol`` px of truth2 (P, 2) for a share >= :func:`goal_share`."""
    what = "matches of the easy points near the true ones"
    pts2 = np.asarray(pts2, float)
    right = right_2d(pts2, truth2, tol)
    share = float(right.mean()) if len(right) else 0.0
    swapped = None if share >= goal_share(ref_share, len(right)) else points_xy_swapped(
        np.nan_to_num(pts2, nan=-1e9), truth2, tol)
    dist = np.linalg.norm(pts2 - truth2, axis=1)
    return _goal(share, ref_share, f"within {tol:g} px", int(right.sum()), len(right), what, [swapped],
                 _where(pts1, np.where(np.isfinite(dist), dist, np.inf), right, "px"))


def right_3d(w, C1, C2, pts1, truth2, tol: float) -> np.ndarray:
    """(P,) bool: w (P, 3) reprojects within tol of pts1 (P, 2) through C1 and of truth2 (P, 2) through C2."""
    d1 = np.linalg.norm(project(C1, w) - pts1, axis=1)
    d2 = np.linalg.norm(project(C2, w) - truth2, axis=1)
    d1, d2 = (np.where(np.isfinite(d), d, np.inf) for d in (d1, d2))
    return (d1 <= tol) & (d2 <= tol)


def right_structure(w, truth3d, tol3d) -> tuple[np.ndarray, np.ndarray]:
    """((P,) bool, (P,) distances): w (P, 3) near truth3d (P, 3) up to a similarity.

    w is moved onto truth3d by the similarity (core.geometry.similarity_fit) that puts the most
    points within tol3d ((P,) or a number, same units as truth3d) of their true point: fits to
    every finite point and to _SAMPLES triples of them (a fixed numpy Generator, so the verdict is
    the same every time; wrong matches must not drag the fit), each refitted twice to the points
    it puts within tolerance.  Distances are those of the best fit (inf for a point that is not
    finite, or everywhere when nothing fits).
    """
    w, truth3d = np.asarray(w, float).reshape(-1, 3), np.asarray(truth3d, float).reshape(-1, 3)
    tol3d = np.broadcast_to(np.asarray(tol3d, float), (len(truth3d),))
    finite = np.flatnonzero(np.all(np.isfinite(w), axis=1))
    best = (np.zeros(len(w), bool), np.full(len(w), np.inf))
    if len(finite) < 3:
        return best
    rng = np.random.default_rng(0)
    starts = [finite] + [rng.choice(finite, 3, replace=False) for _ in range(_SAMPLES)]
    for use in starts:
        for _ in range(3):
            fit = similarity_fit(w[use], truth3d[use]) if len(use) >= 3 else None
            if fit is None:
                break
            s, R, t = fit
            dist = np.full(len(w), np.inf)
            dist[finite] = np.linalg.norm(s * w[finite] @ R.T + t - truth3d[finite], axis=1)
            right = dist <= tol3d
            if right.sum() > best[0].sum():
                best = (right, dist)
            use = np.flatnonzero(right)
    return best


def points3d(w, truth3d, tol3d, ref_share: float = 1.0, pts1=None, M2=None, flat_share: float = 0.0) -> Verdict:
    """3D points w (P, 3) of the easy points pts1 (P, 2) on the true structure (:func:`right_structure`,
    truth3d (P, 3), tol3d (P,)) for a share >= :func:`structure_goal` (``flat_share``: what a flat
    temple reaches there).

    ``M2`` (3, 4), camera 2's pose when the points are in camera 1's frame at the scene's scale,
    lets the catalogue name points behind a camera.
    """
    what = "3D points on the temple's surface (up to a similarity)"
    w = np.asarray(w, float)
    right, dist = right_structure(w, truth3d, tol3d)
    share = float(right.mean()) if len(right) else 0.0
    goal = structure_goal(ref_share, len(right), flat_share)
    behind = None
    if M2 is not None and share < goal and np.all(np.isfinite(w)):
        behind = points_behind_cameras(w, _M1, M2)
    tol3d = np.broadcast_to(np.asarray(tol3d, float), (len(right),))
    flat = [f"a flat temple puts {flat_share:.0%} of them there"] if flat_share > 0 else []
    return _goal(share, ref_share, "near their true point", int(right.sum()), len(right), what, [behind],
                 flat + _where(pts1, dist / tol3d, right, "tolerances"), goal)
