"""Q6: the car sequence's steps with their goals, and the threshold probes.

Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera; C = K M.  Nothing here
reaches a student.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from judging import multiview as jm

from ..scenes import Scenes


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


def _sequence(car, thres: int) -> tuple[Step, ...]:
    from solutions import MultiviewReconstruction

    steps = []
    for t in range(car.n_times):
        C, pts = car.C[t], car.pts[t]
        P_ref, _ = MultiviewReconstruction(C[0], pts[0], C[1], pts[1], C[2], pts[2], thres)
        judged = np.all(np.isfinite(P_ref), axis=1)
        ref_err = float(np.mean(np.linalg.norm(P_ref[judged] - car.P_true[t][judged], axis=1)))
        steps.append(Step(f"time step {t + 1}", np.array(C), np.array(pts), thres, car.P_true[t], judged,
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
        views = rng.permutation(3)
        odd, other = views[0], views[1]
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
    sequence = _sequence(scenes.car, int(rng.choice([400, 500, 600])))
    probes = tuple(_probe(scenes.probe_car, t, int(rng.choice([500, 600, 700])), rng, f"threshold probe {t + 1}")
                   for t in range(2))
    return Multiview(sequence, probes, np.array(scenes.car.P_true, dtype=float))
