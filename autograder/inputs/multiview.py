"""Q6: the car sequence's steps with their goals, and the threshold probes.

Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera; C = K M.  Nothing here
reaches a student.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from judging import multiview as jm

from .scenes import Scenes


@dataclass(frozen=True, eq=False)
class Step:
    """One call: the three cameras C (3, 3, 4), detections pts (3, 12, 3), Thres, and the truth."""

    label: str
    C: np.ndarray
    pts: np.ndarray
    Thres: int
    P_true: np.ndarray
    judged: np.ndarray        # (12,) bool: keypoints that count
    goal: float               # metres: mean distance goal (sequence) or per-point tolerance (probe)


@dataclass(frozen=True, eq=False)
class Multiview:
    sequence: tuple[Step, ...]
    probes: tuple[Step, ...]
    video: np.ndarray         # (T, 12, 3) for the plot


# Keypoints of a step whose confident views are exactly this pair (0-based) and the view left out:
# a reconstruction that, with two confident views, always takes views 1 and 2 uses the left-out one.
_PAIRS = {(0, 2): 1, (1, 2): 0}
_PER_PAIR = 2          # at least this many keypoints of each pair a step
_OFF_PX = (40.0, 80.0)  # how far a left-out view's detection lands from the true pixel


def _occluded_views(pts: np.ndarray, uv: np.ndarray, thres: int, rng) -> np.ndarray:
    """pts (3, N, 3) with at least _PER_PAIR keypoints confident in exactly views (1, 3) and in
    exactly (2, 3), each with its third detection at or below Thres and 40-80 px off its true pixel
    uv (3, N, 2), as a detector reports an occluded keypoint on another part of the car.

    Keypoints that are already so keep their confidences; more are taken from those confident in
    all three views.  The image bounds are not enforced: the reconstruction needs none."""
    pts = np.array(pts, dtype=float)
    for (a, b), odd in _PAIRS.items():
        conf = pts[:, :, 2] > thres
        pair = conf[a] & conf[b] & ~conf[odd]
        spare = np.flatnonzero(conf.all(axis=0))
        extra = rng.permutation(spare)[:max(0, _PER_PAIR - int(pair.sum()))]
        pts[odd, extra, 2] = rng.choice(np.arange(max(thres - 200, 100), thres + 1, 100), size=len(extra))
        for k in (*np.flatnonzero(pair), *extra):
            angle = rng.uniform(0, 2 * np.pi)
            pts[odd, k, :2] = np.rint(uv[odd, k] + rng.uniform(*_OFF_PX) * np.array([np.cos(angle), np.sin(angle)]))
    return pts


def _sequence(car, thres: int, rng) -> tuple[Step, ...]:
    """The car's steps, each with keypoints confident in views (1, 3) and in (2, 3) only (``_occluded_views``)."""
    from solutions import MultiviewReconstruction

    steps = []
    for t in range(car.n_times):
        C, pts = car.C[t], _occluded_views(car.pts[t], car.uv_true[t], thres, rng)
        P_ref, _ = MultiviewReconstruction(C[0], pts[0], C[1], pts[1], C[2], pts[2], thres)
        judged = np.all(np.isfinite(P_ref), axis=1)
        ref_err = float(np.mean(np.linalg.norm(P_ref[judged] - car.P_true[t][judged], axis=1)))
        steps.append(Step(f"time step {t + 1}", np.array(C), pts, thres, car.P_true[t], judged,
                          jm.sequence_goal(ref_err)))
    return tuple(steps)


def _probe(car, t: int, thres: int, rng, label: str) -> Step:
    """Exact detections above Thres and clearly wrong ones at or below it, so that using a detection
    at exactly Thres (``>=``), ignoring the threshold, or leaving out one just above it each puts
    some keypoints off."""
    uv = car.uv_true[t]                                  # (3, 12, 2)
    n = uv.shape[1]
    groups = np.resize(np.array(["at", "below", "just_above", "control"]), n)
    rng.shuffle(groups)
    conf = np.zeros((3, n))
    xy = uv.copy()
    for k, group in enumerate(groups):
        high = rng.choice(np.arange(thres + 200, 1101, 100), size=3)
        conf[:, k] = high
        # The odd view (the one at or below Thres) takes each of the three in turn within a group, so
        # every probe has keypoints confident in views (1, 3) and (2, 3) only, not just (1, 2).
        odd = int(np.sum(groups[:k] == group) % 3)
        other = int(rng.choice([v for v in range(3) if v != odd]))
        if group == "at":
            conf[odd, k] = thres
        elif group == "below":
            conf[odd, k] = rng.choice(np.arange(max(thres - 300, 100), thres, 100))
        elif group == "just_above":
            conf[other, k] = thres + 100
            conf[odd, k] = rng.choice(np.arange(max(thres - 300, 100), thres, 100))
        if group != "control":
            angle = rng.uniform(0, 2 * np.pi)
            xy[odd, k] += rng.uniform(40, 80) * np.array([np.cos(angle), np.sin(angle)])
    pts = np.concatenate([xy, conf[..., None]], axis=2)
    scale = max(1.0, float(np.abs(car.P_true[t]).max()))
    return Step(label, np.array(car.C[t]), pts, thres, car.P_true[t], np.ones(n, bool), 1e-5 * scale)


def prepare_multiview(scenes: Scenes) -> Multiview:
    rng = np.random.default_rng(scenes.seed("multiview"))
    sequence = _sequence(scenes.car, int(rng.choice([400, 500, 600])), rng)
    probes = tuple(_probe(scenes.probe_car, t, int(rng.choice([500, 600, 700])), rng, f"threshold probe {t + 1}")
                   for t in range(2))
    return Multiview(sequence, probes, np.array(scenes.car.P_true, dtype=float))
