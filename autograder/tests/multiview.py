"""Q6 (extra credit): ``MultiviewReconstruction`` and ``plot_3d_keypoint_video`` on hidden car data.

- A hidden car sequence (three cameras, a few time steps, noisy detections): on the keypoints the
  reference reconstructs (two confident views or more), the mean distance of the student's
  points from the true ones must be within 1.5 times the reference's plus 1 cm.
- Threshold probes: exact detections above ``Thres`` and clearly wrong ones at or below it, built
  so that using a detection at exactly Thres (``>=``), ignoring the threshold, or leaving out a
  detection just above it each puts some keypoints off.  Every keypoint must come out right.
- ``plot_3d_keypoint_video`` must run on a (T, 12, 3) sequence, and its figure (returned, or
  opened with pyplot) must show at least 90 % of the keypoints (axes may be swapped or flipped).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from autograder.results import QuestionResult
from autograder.hidden.legacy import Call
from judging import multiview as jm
from judging.verdict import Malformed

from ._common import Outcome, as_array, graded
from .hidden import Scenes

__all__ = ["FUNCTIONS", "QUESTIONS", "calls", "judge", "prepare"]

QUESTIONS = ("Q6",)
FUNCTIONS = ("MultiviewReconstruction", "plot_3d_keypoint_video")
_CALL = "Q6:MultiviewReconstruction"
_PLOT = "Q6:plot_3d_keypoint_video"
_SECONDS_PER_CALL = 5.0
_SECONDS_PLOT = 30.0
_PLOT_SHARE = 0.9
# Plots often show the car with axes swapped or flipped (y up): any signed permutation is fine.
_AXES = [(perm, signs) for perm in itertools.permutations(range(3))
         for signs in itertools.product((1.0, -1.0), repeat=3)]


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
class Prepared:
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
    """Detections with exact positions above Thres and wrong ones at or below it (see the module doc)."""
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


def prepare(scenes: Scenes) -> Prepared:
    rng = np.random.default_rng(scenes.config.seed("multiview"))
    sequence = _sequence(scenes.car, int(rng.choice([400, 500, 600])))
    probes = tuple(_probe(scenes.probe_car, t, int(rng.choice([500, 600, 700])), rng, f"threshold probe {t + 1}")
                   for t in range(2))
    return Prepared(sequence, probes, np.array(scenes.car.P_true, dtype=float))


def calls(p: Prepared, time_scale: float) -> list[Call]:
    items = [((s.C[0], s.pts[0], s.C[1], s.pts[1], s.C[2], s.pts[2], s.Thres), {}) for s in (*p.sequence, *p.probes)]
    budget = _SECONDS_PER_CALL * len(items) * time_scale
    plot_budget = _SECONDS_PLOT * time_scale
    return [
        Call(_CALL, "__hw4_each", ("MultiviewReconstruction", items, budget), timeout=budget + 2),
        Call(_PLOT, "__hw4_plot", ("plot_3d_keypoint_video", (p.video,)), timeout=plot_budget + 2),
    ]


def drawn_share(drawn: np.ndarray, video: np.ndarray) -> float:
    """Share of the sequence's keypoints (T, N, 3) that appear among the drawn 3D points (K, 3),
    up to a signed permutation of the axes and 1e-6 of the scene's size."""
    truth = video.reshape(-1, 3)
    truth = truth[np.all(np.isfinite(truth), axis=1)]
    drawn = drawn[np.all(np.isfinite(drawn), axis=1)]
    if len(truth) == 0 or len(drawn) == 0:
        return 0.0
    tol = 1e-6 * max(1.0, float(np.abs(truth).max()))
    best = 0.0
    for perm, signs in _AXES:
        moved = truth[:, perm] * signs
        # Sorting by one coordinate lets each keypoint be looked up among nearby candidates only.
        order = np.argsort(drawn[:, 0])
        xs = drawn[order, 0]
        lo = np.searchsorted(xs, moved[:, 0] - tol)
        hi = np.searchsorted(xs, moved[:, 0] + tol, side="right")
        hits = sum(bool(np.any(np.all(np.abs(drawn[order[a:b]] - m) <= tol, axis=1))) for m, a, b in zip(moved, lo, hi))
        best = max(best, hits / len(truth))
    return best


def _P(item, n) -> np.ndarray:
    if not item.ok:
        raise Malformed(item.error)
    return jm.read_P(item.value, n)


def judge(p: Prepared, outcomes) -> list[QuestionResult]:
    steps = (*p.sequence, *p.probes)
    items = Outcome(outcomes.get(_CALL), "MultiviewReconstruction").items(len(steps))
    seq_right, seq_lines = 0, []
    probe_right, probe_lines, mistakes = 0, [], []
    for step, item in zip(steps, items):
        is_probe = step in p.probes
        lines = probe_lines if is_probe else seq_lines
        try:
            P = _P(item, len(step.P_true))
        except Malformed as exc:
            lines.append(f"{step.label}: {exc}")
            continue
        if is_probe:
            v = jm.threshold_probe(P, step.P_true, step.pts[:, :, 2].T, step.Thres, step.goal)
            probe_right += v.passed
            mistakes += v.mistakes
            lines.append(f"{step.label} (Thres = {step.Thres}): {v.measured.split(' within')[0]} keypoints right")
        else:
            v = jm.sequence(P, step.P_true, step.judged, step.goal)
            seq_right += v.passed
            lines.append(f"{step.label}: {v.measured} m of your keypoints from the true ones (goal {v.goal} m)")
    plot = Outcome(outcomes.get(_PLOT), "plot_3d_keypoint_video").items(1)[0]
    drew, plot_lines = False, [plot.error]
    if plot.ok:
        try:
            shown = drawn_share(as_array(plot.value, (None, 3), "the drawn points"), p.video)
        except Malformed:
            shown = 0.0
        drew = shown >= _PLOT_SHARE
        plot_lines = [f"your figure shows {shown:.0%} of the keypoints of the sequence (goal >= {_PLOT_SHARE:.0%})"]
    tests = [
        graded("3D keypoints of a hidden car sequence", 9, seq_right / len(p.sequence), seq_lines),
        graded("only detections above Thres are used", 4, probe_right / len(p.probes), probe_lines, mistakes),
        graded("plot_3d_keypoint_video draws a sequence", 2, float(drew), plot_lines),
    ]
    return [QuestionResult.of("Q6", tests)]
