"""Q6, ``MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres) -> (P, err)``: keypoints near the truth.

Two rules: on data built to expose threshold mistakes (exact detections above Thres, clearly
wrong ones at or below it) every keypoint is right; on an ordinary noisy sequence the mean
distance from the truth is close to a reference reconstruction's.  And err must be the total
squared reprojection error of the returned P over the detections used (:func:`err_reported`).
"""

from __future__ import annotations

import numpy as np

from core.geometry import project

from .mistakes import error_not_sum_of_squares, threshold_mistakes
from .verdict import Malformed, Verdict, fmt, read_array, read_number, read_parts

__all__ = ["ERR_RTOL", "err_bounds", "err_reported", "err_totals", "read_P", "read_P_err", "reprojects_near", "sequence",
           "sequence_goal", "threshold_probe"]

ERR_RTOL = 1e-3   # err within this share of the bounds recomputed from P (as bundle adjustment's o1, o2)


def read_P(value, n: int) -> np.ndarray:
    """P (n, 3) from MultiviewReconstruction's result ((P, err), or P alone), or Malformed."""
    if isinstance(value, (tuple, list)):
        value = read_parts(value, 1, "MultiviewReconstruction")[0]
    return read_array(value, (n, 3), "P")


def read_P_err(value, n: int) -> tuple[np.ndarray, object]:
    """(P (n, 3), err as returned, or None when P came alone) from MultiviewReconstruction's result, or Malformed."""
    if isinstance(value, (tuple, list)):
        P = read_parts(value, 1, "MultiviewReconstruction")[0]
        return read_array(P, (n, 3), "P"), (value[1] if len(value) > 1 else None)
    return read_array(value, (n, 3), "P"), None


def _squared(P, Cs, pts, Thres) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(confident (N, V) bool: above Thres, finite (N,) bool: keypoints with a finite point in P,
    squared distances (N, V) of P's projections from the detections, residuals (N, V, 2))."""
    P = np.asarray(P, float)
    xy = np.stack([np.asarray(p, float)[:, :2] for p in pts], axis=1)                  # (N, V, 2)
    confident = np.stack([np.asarray(p, float)[:, 2] > Thres for p in pts], axis=1)    # (N, V)
    with np.errstate(all="ignore"):
        r = np.stack([xy[:, v] - project(Cs[v], P) for v in range(len(pts))], axis=1)
        sq = np.sum(r ** 2, axis=2)
    return confident, np.all(np.isfinite(P), axis=1), sq, r


def err_bounds(P, Cs, pts, Thres) -> tuple[float, float]:
    """(lowest, highest) total squared reprojection error (pixels^2) that P (N, 3) can report over
    the detections it used (pts: three (N, 3) arrays [x, y, confidence], Cs: three (3, 4) cameras).

    Which detections a student used is the threshold checks' business, so the bounds take any
    choice: from the two best-fitting detections above Thres of each keypoint seen so twice or
    more (a method using two of three views) to every detection of every keypoint P holds; a
    keypoint left NaN counts nothing.  inf when such a detection's projection is not finite.
    """
    confident, finite, sq, _ = _squared(P, Cs, pts, Thres)
    if not np.all(np.isfinite(sq[finite])):
        return float("inf"), float("inf")
    rows = finite & (confident.sum(axis=1) >= 2)
    two = np.sort(np.where(confident, sq, np.inf)[rows], axis=1)[:, :2]
    return float(np.sum(two)), float(np.sum(sq[finite]))


def err_totals(P, Cs, pts, Thres) -> list[float]:
    """The totals (pixels^2) an err of P may be: P's squared reprojection errors summed over the
    detections each known way of choosing them keeps, the same way for every keypoint (a keypoint
    left NaN counts nothing): the detections above Thres (or at or above it) of each keypoint with
    two of them, the two that fit best, the two most confident, the first two in view order, or
    every detection.  An err between two of these, which no one choice gives, is not P's."""
    P = np.asarray(P, float)
    conf = np.stack([np.asarray(p, float)[:, 2] for p in pts], axis=1)               # (N, V)
    _, finite, sq, _ = _squared(P, Cs, pts, Thres)
    totals = [float(np.sum(sq[finite]))]                                              # every detection
    order = np.arange(conf.shape[1])
    for above in (conf > Thres, conf >= Thres):
        rows = finite & (above.sum(axis=1) >= 2)
        picks = [above,
                 _two(above, np.where(above, sq, np.inf)),          # the two that fit best
                 _two(above, np.where(above, -conf, np.inf)),       # the two most confident
                 _two(above, np.where(above, order, np.inf))]       # the first two in view order
        totals += [float(np.sum(np.where(pick, sq, 0.0)[rows])) for pick in picks]
    return totals


def _two(allowed: np.ndarray, key: np.ndarray) -> np.ndarray:
    """(N, V) bool: per row, the two allowed entries with the smallest ``key``."""
    picked = np.zeros_like(allowed)
    idx = np.argsort(key, axis=1, kind="stable")[:, :2]
    np.put_along_axis(picked, idx, True, axis=1)
    return picked & allowed


def err_reported(err, P, Cs, pts, Thres) -> Verdict:
    """err is the total squared reprojection error of the returned P (N, 3) over the detections used
    (one of :func:`err_totals`, within relative ERR_RTOL plus 1e-6 px^2 a keypoint); names
    error_not_sum_of_squares only when err is a known variant (a mean, a root...) of the sum over
    the detections above Thres: an err that matches none may count other detections (below Thres,
    or of keypoints P leaves out), which this test cannot tell from a wrong formula."""
    what = "err is the total squared reprojection error of P over the detections used"
    if err is None:
        return Verdict.of(what, False, "MultiviewReconstruction returned P alone", "(P, err)")
    try:
        e = read_number(err, "err")
    except Malformed as exc:
        return Verdict.failed(what, str(exc))
    low, high = err_bounds(P, Cs, pts, Thres)
    if not np.isfinite(high):
        return Verdict.of(what, False, "P does not project to finite pixels", "")
    slack = 1e-6 * max(len(np.asarray(P)), 1)
    # Within the bounds is not enough: the total of one choice of detections (an err of another
    # P, say one fitted to every detection, falls between them).
    ok = bool(np.isfinite(e) and any(abs(e - t) <= ERR_RTOL * t + slack for t in err_totals(P, Cs, pts, Thres)))
    goal = fmt(high) if np.isclose(low, high, rtol=ERR_RTOL) else f"{fmt(low)} to {fmt(high)}"
    found = []
    if not ok:
        confident, finite, _, r = _squared(P, Cs, pts, Thres)
        used = confident & finite[:, None] & (confident.sum(axis=1) >= 2)[:, None]
        found.append(error_not_sum_of_squares(e, r[used], rtol=ERR_RTOL, only_named=True))
    return Verdict.of(what, ok, f"err = {fmt(e)} px^2", f"{goal} px^2 from your P", found)


def _distances(P, P_true) -> np.ndarray:
    d = np.linalg.norm(np.asarray(P, float) - P_true, axis=1)
    return np.where(np.isfinite(d), d, np.inf)


def threshold_probe(P, P_true, conf, Thres, tol: float) -> Verdict:
    """Every keypoint of P (N, 3) within ``tol`` of P_true (N, 3), on detections whose confidences
    conf (N, V) make every one at or below Thres wrong; names the threshold mistake."""
    what = f"keypoints right, Thres = {Thres:g}"
    right = _distances(P, P_true) <= tol
    ok = bool(right.all())
    found = () if ok else threshold_mistakes(P, P_true, conf, Thres, tol)
    return Verdict.of(what, ok, f"{int(right.sum())} of {len(right)} within {fmt(tol)}", "all", found)


def sequence_goal(ref_mean: float) -> float:
    """The goal (scene units, metres) of :func:`sequence` from a reference's mean distance on the same data."""
    return 1.5 * float(ref_mean) + 0.01


def sequence(P, P_true, judged, goal: float) -> Verdict:
    """Mean distance of P (N, 3) from P_true (N, 3) over the ``judged`` (N,) keypoints <= goal."""
    what = "keypoints near the true ones"
    d = _distances(P, P_true)[np.asarray(judged, bool)]
    mean = float(np.mean(d)) if len(d) else 0.0
    return Verdict.of(what, mean <= goal, f"mean distance {fmt(mean)}", f"<= {fmt(goal)}")


def reprojects_near(P, Cs, pts, Thres, median_px: float = 10.0) -> Verdict:
    """Without ground truth: every keypoint with two detections above Thres is reconstructed, and
    the median reprojection distance to the detections used is at most ``median_px``.

    Cs : (3, 3, 4) cameras; pts : three (N, 3) arrays [x, y, confidence].
    """
    what = "keypoints seen confidently twice are reconstructed near their detections"
    P = np.asarray(P, float)
    used = np.stack([np.asarray(p)[:, 2] > Thres for p in pts], axis=1)
    need = used.sum(axis=1) >= 2
    done = need & np.all(np.isfinite(P), axis=1)
    d = [np.linalg.norm(project(Cs[c], P[done]) - np.asarray(pts[c], float)[done, :2], axis=1)[used[done, c]]
         for c in range(len(pts))]
    d = np.concatenate(d) if done.any() else np.array([np.inf])
    med = float(np.median(d)) if len(d) else np.inf
    ok = done.sum() == need.sum() and med <= median_px
    return Verdict.of(what, ok, f"{int(done.sum())} of {int(need.sum())} reconstructed, median {fmt(med)} px",
                      f"all, <= {median_px:g} px")
