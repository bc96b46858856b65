"""Q6, ``MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres) -> (P, err)``: keypoints near the truth.

Two rules: on data built to expose threshold mistakes (exact detections above Thres, clearly
wrong ones at or below it) every keypoint is right; on an ordinary noisy sequence the mean
distance from the truth is close to a reference reconstruction's.
"""

from __future__ import annotations

import numpy as np

from core.geometry import project

from .mistakes import threshold_mistakes
from .verdict import Verdict, fmt, read_array, read_parts

__all__ = ["read_P", "reprojects_near", "sequence", "sequence_goal", "threshold_probe"]


def read_P(value, n: int) -> np.ndarray:
    """P (n, 3) from MultiviewReconstruction's result ((P, err), or P alone), or Malformed."""
    if isinstance(value, (tuple, list)):
        value = read_parts(value, 1, "MultiviewReconstruction")[0]
    return read_array(value, (n, 3), "P")


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
