"""Q3.2, ``triangulate(C1, pts1, C2, pts2) -> (w, err)``: the points and their error.

Every error is recomputed here from the returned points (core.geometry.project): the sum over
the points of |x1 - proj(C1, w)|^2 + |x2 - proj(C2, w)|^2, pixels^2.
"""

from __future__ import annotations

import numpy as np

from core.geometry import project

from .mistakes import error_not_sum_of_squares, points_behind_cameras, w_not_divided
from .verdict import Malformed, Verdict, fmt, read_array, read_number, read_parts

__all__ = ["ERR_RTOL", "EXACT_RTOL", "LINEAR_SLACK", "err_reported", "exact_points", "noisy_error", "optimal_error",
           "read_w_err", "reprojection_error", "residuals"]

EXACT_RTOL = 1e-6     # noise-free matches: every point within EXACT_RTOL of the scene's size of the truth
LINEAR_SLACK = 1.2    # noisy matches: error at most 20 % above a linear triangulation's (plus 1e-6 px^2 a point)
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


def optimal_error(C1, pts1, C2, pts2, *starts, iterations: int = 30) -> float:
    """The lowest total squared reprojection error (pixels^2) reachable by moving each point alone:
    a damped Gauss-Newton polish of every start (N, 3) (e.g. the true points, or the student's
    own), the best per point kept; inf when no start has a finite point.

    It is a lower bound (to the polish's precision) of what any triangulation of these matches
    with these cameras reaches near those starts, computed from the data alone, with no
    reference triangulation: the public checks' goal where the hidden tests use the reference's.
    """
    p1, p2 = np.asarray(pts1, float), np.asarray(pts2, float)

    def res(X):
        with np.errstate(all="ignore"):
            return np.concatenate([p1 - project(C1, X), p2 - project(C2, X)], axis=1)   # (N, 4)

    def cost(X):
        c = np.sum(res(X) ** 2, axis=1)
        return np.where(np.isfinite(c), c, np.inf)

    best = np.full(len(p1), np.inf)
    for start in starts:
        if start is None:
            continue
        X = np.array(start, dtype=float).reshape(len(p1), 3)
        lam = np.full(len(X), 1e-3)
        c = cost(X)
        for _ in range(iterations):
            r = res(X)
            J = np.empty((len(X), 4, 3))
            eps = 1e-7 * np.maximum(1.0, np.abs(X).max(axis=1))
            for k in range(3):
                d = np.zeros_like(X)
                d[:, k] = eps
                J[:, :, k] = (res(X + d) - r) / eps[:, None]
            with np.errstate(all="ignore"):
                A = np.einsum("nik,nil->nkl", J, J)
                A += lam[:, None, None] * np.eye(3) * np.maximum(np.trace(A, axis1=1, axis2=2) / 3, 1e-12)[:, None, None]
                g = np.einsum("nik,ni->nk", J, r)
                ok = np.all(np.isfinite(A), axis=(1, 2)) & np.all(np.isfinite(g), axis=1)
                step = np.zeros_like(X)
                if ok.any():
                    step[ok] = np.linalg.solve(A[ok], -g[ok][..., None])[..., 0]
            trial = X + step
            ct = cost(trial)
            better = ct < c
            X[better], c[better] = trial[better], ct[better]
            lam = np.where(better, lam / 3, lam * 4)
        best = np.minimum(best, c)
    total = float(np.sum(best))
    return total if np.isfinite(total) else float("inf")


def _scene_size(X) -> float:
    return max(float(np.median(np.linalg.norm(np.asarray(X, float), axis=1))), 1e-12)


def _why_points_wrong(ok, w, M2, **given) -> list:
    """The catalogue's reason for wrong points: w not divided (named alone), else points behind a camera."""
    if ok or not np.all(np.isfinite(w)):
        return []
    undivided = w_not_divided(w, **given)
    if undivided is not None:
        return [undivided]
    return [points_behind_cameras(w, _M1, M2)] if M2 is not None else []


def exact_points(w, X, M2=None) -> Verdict:
    """Noise-free matches give the true points X (N, 3): every |w - X| <= EXACT_RTOL * median |X|.

    ``M2`` (3, 4), camera 2's pose, lets the catalogue name points behind a camera.
    """
    what = "noise-free matches give the true 3D points"
    w = np.asarray(w, float)
    with np.errstate(invalid="ignore", over="ignore"):
        gap = float(np.max(np.linalg.norm(w - X, axis=1))) / _scene_size(X) if np.all(np.isfinite(w)) else np.inf
    ok = gap <= EXACT_RTOL
    found = _why_points_wrong(ok, w, M2, X=np.asarray(X, float))
    return Verdict.of(what, ok, f"largest error {fmt(gap)} of the scene's size", f"<= {EXACT_RTOL:g}", found)


def noisy_error(w, C1, pts1, C2, pts2, linear_err: float, M2=None) -> Verdict:
    """On noisy matches, w's error (recomputed) is at most LINEAR_SLACK times a linear triangulation's.

    linear_err : the total squared error of a linear triangulation of the same matches with the
        same cameras (the reference's in the grader); the public checks give the lower bound of
        :func:`optimal_error` instead (they have no reference).  An optimal triangulation passes.
    """
    what = "reprojection error as low as a linear triangulation's"
    n = len(np.asarray(pts1))
    total = reprojection_error(C1, pts1, C2, pts2, w)
    goal = LINEAR_SLACK * float(linear_err) + 1e-6 * max(n, 1)
    ok = total <= goal
    found = _why_points_wrong(ok, w, M2, cameras=(C1, pts1, C2, pts2))
    return Verdict.of(what, ok, f"{fmt(total)} px^2", f"<= {fmt(goal)} px^2", found)


def err_reported(err, w, C1, pts1, C2, pts2) -> Verdict:
    """err is the total squared reprojection error of the returned w in both images (relative ERR_RTOL)."""
    what = "err is the sum of squared reprojection errors of w"
    r1, r2 = residuals(C1, pts1, C2, pts2, w)
    total = reprojection_error(C1, pts1, C2, pts2, w)
    if not np.isfinite(total):
        return Verdict.of(what, False, "w does not project to finite pixels", "")
    m = error_not_sum_of_squares(err, r1, r2, rtol=ERR_RTOL)
    if m is not None:
        # err may be right for the points the student meant, w itself being what is wrong.
        m = w_not_divided(np.asarray(w, float), cameras=(C1, pts1, C2, pts2)) or m
    try:
        shown = fmt(read_number(err, "err"))
    except Malformed:
        shown = "not a number"
    return Verdict.of(what, m is None, f"err = {shown}", f"{fmt(total)} from your w", [m])
