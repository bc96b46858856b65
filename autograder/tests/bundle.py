"""Q5: ``rodriguesResidual`` and ``bundleAdjustment`` on hidden two-view problems.

Each problem takes the 3D points of a hidden temple scene and views them from a second camera
swung further round (a well-conditioned problem, so that the handout's ``minimize`` converges
in seconds), with 0.5 px of noise.  The start is deliberately off: camera 2's rotation 1 degree
and its translation direction 5 degrees away from the truth, |t| = 1 as ``findM2`` gives, and
the points triangulated from that camera.

- ``rodriguesResidual`` must return the handout's residuals, in the handout's layout (or their
  negatives), at the start of each problem and at a perturbed x.
- ``bundleAdjustment``'s result is judged by judging.bundle.result: the reprojection error
  recomputed from the returned M2 and w, full marks within 2 % of the optimum (the reference's,
  or a gauge-fixed Levenberg-Marquardt solve made here, whichever is lower), partial credit on
  a log scale from the start; and the reconstruction compared with the start's after a
  similarity alignment.  Any gauge is right (the handout fixes no scale); |t| is not judged.
- M2 must hold a rotation, and o1, o2 the errors before and after.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.optimize

from autograder.results import QuestionResult
from autograder.hidden.legacy import Call
from core.geometry import project
from judging import bundle as jb
from judging.bundle import total_error
from judging.verdict import Malformed

from ._common import Outcome, first_problem, graded
from .hidden import Scenes

__all__ = ["FUNCTIONS", "QUESTIONS", "calls", "judge", "prepare"]

QUESTIONS = ("Q5",)
FUNCTIONS = ("rodriguesResidual", "bundleAdjustment")
_SECONDS_RESIDUAL = 2.0
_SECONDS_BA = 60.0
_M1 = np.hstack([np.eye(3), np.zeros((3, 1))])
_SWING_DEG = 20.0
_NOISE_PX = 0.5


@dataclass(frozen=True, eq=False)
class Problem:
    label: str
    K1: np.ndarray
    K2: np.ndarray
    p1: np.ndarray
    p2: np.ndarray
    M2_init: np.ndarray
    w_init: np.ndarray
    start: float       # total squared reprojection error at the start
    optimum: float     # the lowest error found here with |t| held


@dataclass(frozen=True, eq=False)
class Prepared:
    problems: tuple[Problem, ...]
    residual_inputs: tuple[tuple, ...]     # (K1, M1, p1, K2, p2, x) of rodriguesResidual
    residual_expected: tuple[np.ndarray, ...]


def _rotation(axis, degrees) -> np.ndarray:
    from starter import rodrigues

    axis = np.asarray(axis, float)
    return rodrigues(np.radians(degrees) * axis / np.linalg.norm(axis))


def _gauge_fixed_optimum(K1, K2, p1, p2, M2_init, w_init) -> float:
    # t moves on the sphere of its initial length through two tangent coordinates, so the
    # scale cannot collapse; Levenberg-Marquardt from the start converges in a few dozen steps.
    from starter import invRodrigues, rodrigues

    n = len(p1)
    t0 = M2_init[:, 3]
    radius = np.linalg.norm(t0)
    direction = t0 / radius
    tangent = np.linalg.svd(direction[None, :])[2][1:].T

    def residuals(z):
        d = direction + tangent @ z[-2:]
        M2 = np.hstack([rodrigues(z[3 * n:3 * n + 3]), (radius * d / np.linalg.norm(d))[:, None]])
        w = z[:3 * n].reshape(n, 3)
        return np.concatenate([(p1 - project(K1 @ _M1, w)).ravel(), (p2 - project(K2 @ M2, w)).ravel()])

    z0 = np.concatenate([w_init.ravel(), invRodrigues(M2_init[:, :3]), np.zeros(2)])
    fit = scipy.optimize.least_squares(residuals, z0, method="lm")
    return float(np.sum(fit.fun ** 2))


def _problem(label, scene, count, rng) -> Problem:
    from solutions import bundleAdjustment, triangulate

    idx = np.sort(rng.choice(len(scene.X), size=min(count, len(scene.X)), replace=False))
    X = scene.X[idx]
    centre = X.mean(axis=0)
    axis = np.array([rng.normal(), rng.normal(), 0.2 * rng.normal()])
    R = _rotation(axis, _SWING_DEG)
    t = centre - R @ centre                     # turns the world about the points' centre
    K1, K2 = scene.K1, scene.K2
    p1 = project(K1 @ _M1, X) + _NOISE_PX * rng.normal(size=(len(X), 2))
    p2 = project(K2 @ np.hstack([R, t[:, None]]), X) + _NOISE_PX * rng.normal(size=(len(X), 2))
    R0 = _rotation(rng.normal(size=3), 2.0) @ R
    t0 = _rotation(rng.normal(size=3), 5.0) @ (t / np.linalg.norm(t))
    M2_init = np.hstack([R0, t0[:, None]])
    w_init, _ = triangulate(K1 @ _M1, p1, K2 @ M2_init, p2)
    start = total_error(K1, K2, p1, p2, M2_init, w_init)
    optimum = _gauge_fixed_optimum(K1, K2, p1, p2, M2_init, w_init)
    M2_ref, w_ref, _, _ = bundleAdjustment(K1, _M1, p1, K2, M2_init, p2, w_init)
    if np.linalg.norm(M2_ref[:, 3]) >= 0.5 * np.linalg.norm(M2_init[:, 3]):  # a collapsed optimum is no goal
        optimum = min(optimum, total_error(K1, K2, p1, p2, M2_ref, w_ref))
    return Problem(label, K1, K2, p1, p2, M2_init, w_init, start, optimum)


def _x_of(problem: Problem) -> np.ndarray:
    from starter import invRodrigues

    return np.concatenate([problem.w_init.ravel(), invRodrigues(problem.M2_init[:, :3]), problem.M2_init[:, 3]])


def prepare(scenes: Scenes) -> Prepared:
    from solutions import rodriguesResidual

    rng = np.random.default_rng(scenes.config.seed("bundle"))
    problems = tuple(_problem(tc.label, tc.scene, scenes.config.ba_points, rng) for tc in scenes.hidden[:2])
    inputs = []
    for k, pr in enumerate(problems):
        x = _x_of(pr)
        if k == 0:
            x = x + rng.normal(scale=0.01, size=x.shape)   # away from the start, where r2 matters too
        inputs.append((pr.K1, _M1, pr.p1, pr.K2, pr.p2, x))
    expected = tuple(rodriguesResidual(*inp) for inp in inputs)
    return Prepared(problems, tuple(inputs), expected)


def calls(p: Prepared, time_scale: float) -> list[Call]:
    res_items = [(inp, {}) for inp in p.residual_inputs]
    ba_items = [((pr.K1, _M1, pr.p1, pr.K2, pr.M2_init, pr.p2, pr.w_init), {}) for pr in p.problems]
    res_budget = _SECONDS_RESIDUAL * len(res_items) * time_scale
    ba_budget = _SECONDS_BA * len(ba_items) * time_scale
    return [
        Call("Q5:rodriguesResidual", "__hw4_each", ("rodriguesResidual", res_items, res_budget),
             timeout=res_budget + 2),
        Call("Q5:bundleAdjustment", "__hw4_each", ("bundleAdjustment", ba_items, ba_budget),
             timeout=ba_budget + 5),
    ]


def _judge_residuals(p: Prepared, outcomes):
    items = Outcome(outcomes.get("Q5:rodriguesResidual"), "rodriguesResidual").items(len(p.residual_inputs))
    right, lines, mistakes = 0, [], []
    for k, (inp, item) in enumerate(zip(p.residual_inputs, items), start=1):
        try:
            if not item.ok:
                raise Malformed(item.error)
            r = jb.read_residuals(item.value, len(inp[2]))
        except Malformed as exc:
            lines.append(f"input {k}: {exc}")
            continue
        v = jb.residuals(r, *inp)
        right += v.passed
        lines.append(f"input {k}: {v.sentence}")
        mistakes += v.mistakes
    return graded("rodriguesResidual returns the handout's residuals", 6, right / len(items), lines, mistakes)


def _judge_ba(p: Prepared, outcomes):
    items = Outcome(outcomes.get("Q5:bundleAdjustment"), "bundleAdjustment").items(len(p.problems))
    opt_tests, rot_ok, rep_ok = [], [], []
    rot_lines, rep_lines, rep_mistakes = [], [], []
    for pr, item in zip(p.problems, items):
        try:
            if not item.ok:
                raise Malformed(item.error)
            M2, w, o1, o2 = jb.read_ba(item.value, len(pr.p1))
        except Malformed as exc:
            opt_tests.append(graded(f"bundle adjustment on {pr.label}", 5, 0.0, [f"{pr.label}: {exc}"]))
            rot_ok.append(False)
            rep_ok.append(False)
            continue
        args = (pr.K1, pr.K2, pr.p1, pr.p2, pr.M2_init, pr.w_init)
        v = jb.result(M2, w, *args, pr.optimum)
        opt_tests.append(graded(f"bundle adjustment on {pr.label}", 5, v.fraction,
                                [f"{pr.label}: {v.sentence}", *v.lines], v.mistakes))
        r = jb.rotation(M2)
        rot_ok.append(r.passed)
        rot_lines.append(f"{pr.label}: M2[:, :3] is {'' if r.passed else 'not '}a rotation")
        e = jb.reported_errors(o1, o2, M2, w, *args)
        rep_ok.append(e.passed)
        rep_lines.append(f"{pr.label}: {e.measured}; your start and result give {e.goal.split(' from')[0]} px^2")
        rep_mistakes += e.mistakes
    for lines in (rot_lines, rep_lines):
        if not lines:
            lines.append(first_problem(items) or "no result to check")
    return opt_tests + [
        graded("M2 holds a rotation", 2, float(all(rot_ok)), rot_lines),
        graded("o1 and o2 are the reprojection errors before and after", 2, float(all(rep_ok)), rep_lines,
               rep_mistakes),
    ]


def judge(p: Prepared, outcomes) -> list[QuestionResult]:
    tests = [_judge_residuals(p, outcomes), *_judge_ba(p, outcomes)]
    return [QuestionResult.of("Q5", tests)]
