"""Q3.3, ``findM2(F, pts1, pts2, K1, K2) -> (M2, C2, w)``: the right camera of the four.

E fixes camera 2 up to the four candidates of ``starter.camera2`` and the scale of t, so M2 is
compared with the right candidate by rotation angle and direction of t only.
"""

from __future__ import annotations

import numpy as np

from .mistakes import one_camera_depth, points_behind_cameras, same_up_to_scale, wrong_camera
from .triangulation import LINEAR_SLACK, reprojection_error
from .verdict import Malformed, Verdict, fmt, read_array, read_parts

__all__ = ["DIR_TOL_DEG", "ROT_TOL_DEG", "is_rotation", "outputs", "pose_gap", "read_findM2", "right_camera"]

ROT_TOL_DEG = 0.5
DIR_TOL_DEG = 1.0
_M1 = np.hstack([np.eye(3), np.zeros((3, 1))])


def read_findM2(value, n: int) -> tuple[np.ndarray, object, object]:
    """(M2 (3, 4), C2 as returned or None, w as returned or None) from findM2's result, or Malformed.

    findM2 returns (M2, C2, w); M2 alone is read too (C2 and w are then None).  Five or more
    values in any order (Fall 2023's findM2 returned M1 and C1 too) are read by what each is: w
    the one (n, 3) array, M1 and C1 the 3 x 4 matrices with a zero last column, M2 the other
    3 x 4 whose left block is a rotation, C2 the remaining one.
    """
    if isinstance(value, (tuple, list)) and len(value) > 3:
        found = _by_role(value, n)
        if found is not None:
            return found
    if isinstance(value, (tuple, list)):
        parts = read_parts(value, 1, "findM2")
        M2 = read_array(parts[0], (3, 4), "M2")
        rest = tuple(value[1:3]) + (None, None)
        return M2, rest[0], rest[1]
    return read_array(value, (3, 4), "M2"), None, None


def _by_role(value, n: int):
    """(M2, C2, w) picked from a longer tuple by shape and content, or None when that is ambiguous."""
    arrays = []
    for v in value:
        try:
            arrays.append(np.asarray(v, dtype=float))
        except (TypeError, ValueError):
            arrays.append(None)
    points = [a for a in arrays if a is not None and a.shape == (n, 3)]
    cameras = [a for a in arrays if a is not None and a.shape == (3, 4) and np.all(np.isfinite(a))
               and np.any(a[:, 3] != 0)]   # M1 = [I | 0] and C1 = K1 [I | 0] have t = 0
    poses = [a for a in cameras if is_rotation(a[:, :3], atol=1e-4)]
    if len(points) != 1 or len(cameras) != 2 or len(poses) != 1:
        return None
    M2 = poses[0]
    C2 = next(a for a in cameras if a is not M2)
    return M2, C2, points[0]


def _angle(u, v) -> float:
    nu, nv = np.linalg.norm(u), np.linalg.norm(v)
    if not (np.isfinite(nu) and np.isfinite(nv)) or nu == 0 or nv == 0:
        return 180.0
    return float(np.degrees(np.arccos(np.clip(np.dot(u, v) / (nu * nv), -1.0, 1.0))))


def pose_gap(M2, right) -> tuple[float, float]:
    """(rotation angle between the R's, angle between the t's), degrees; 180 for unusable input."""
    M2, right = np.asarray(M2, float), np.asarray(right, float)
    if not np.all(np.isfinite(M2)):
        return 180.0, 180.0
    c = (np.trace(M2[:, :3].T @ right[:, :3]) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))), _angle(M2[:, 3], right[:, 3])


def is_rotation(R, atol: float = 1e-6) -> bool:
    """R (3, 3) is a proper rotation: R^T R = I to ``atol`` and det R = +1."""
    R = np.asarray(R, float)
    return bool(R.shape == (3, 3) and np.all(np.isfinite(R)) and np.allclose(R.T @ R, np.eye(3), atol=atol)
                and np.linalg.det(R) > 0)


def right_camera(M2, right, X=None) -> Verdict:
    """M2 (3, 4) holds a rotation and is ``right`` (3, 4): R within ROT_TOL_DEG, t's direction within DIR_TOL_DEG.

    ``right`` is the candidate nearest the true pose (or the reference's choice when there is no
    truth).  The scale of t is free.  Names the wrong candidate of the four; with the true points
    X (N, 3) (in ``right``'s scale), a candidate that puts them all in front of one camera and behind
    the other is named as a depth test of one camera only.
    """
    what = "M2 is the right camera of the four"
    M2 = np.asarray(M2, float)
    if not is_rotation(M2[:, :3]):
        return Verdict.of(what, False, "M2[:, :3] is not a rotation", "R^T R = I, det R = +1")
    rot, direction = pose_gap(M2, right)
    ok = rot <= ROT_TOL_DEG and direction <= DIR_TOL_DEG
    named = ()
    if not ok:
        named = [(one_camera_depth(M2, right, X) if X is not None else None) or wrong_camera(M2, right)]
    return Verdict.of(what, ok, f"R off by {fmt(rot)} deg, t by {fmt(direction)} deg",
                      f"<= {ROT_TOL_DEG:g} and {DIR_TOL_DEG:g} deg", named)


def outputs(M2, C2, w, K1, K2, pts1, pts2, linear_err: float) -> Verdict:
    """C2 = K2 M2 (up to scale) and w (N, 3) reprojects through K1 [I | 0] and C2 no worse than
    LINEAR_SLACK times ``linear_err`` (a linear triangulation's error with those cameras) plus 1e-6 px^2 a point.

    C2 and w are the values as returned (None when findM2 returned M2 alone); names points behind.
    """
    what = "C2 = K2 M2 and w are the points triangulated with it"
    if C2 is None or w is None:
        return Verdict.of(what, False, "findM2 should return (M2, C2, w)", "")
    try:
        C2 = read_array(C2, (3, 4), "C2")
        w = read_array(w, (len(np.asarray(pts1)), 3), "w")
    except Malformed as exc:
        return Verdict.failed(what, str(exc))
    M2 = np.asarray(M2, float)
    K1, K2 = np.asarray(K1, float), np.asarray(K2, float)
    if not same_up_to_scale(C2, K2 @ M2, 1e-6):
        return Verdict.of(what, False, "C2 is not K2 @ M2", "C2 = K2 M2")
    n = len(w)
    err = reprojection_error(K1 @ _M1, pts1, C2, pts2, w)
    goal = LINEAR_SLACK * float(linear_err) + 1e-6 * max(n, 1)
    ok = err <= goal
    behind = points_behind_cameras(w, _M1, M2) if np.all(np.isfinite(w)) else None
    return Verdict.of(what, ok and behind is None, f"reprojection error of w {fmt(err)} px^2", f"<= {fmt(goal)} px^2",
                      [behind], because="the error meets its goal, but most points are behind a camera" if ok else "")
