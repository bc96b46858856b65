"""Q5: ``rodriguesResidual`` and ``bundleAdjustment`` on hidden two-view problems.

Each problem takes the 3D points of a hidden temple scene and views them from a second camera
swung further round (a well-conditioned problem, so that the handout's ``minimize`` converges
in seconds), with 0.5 px of noise.  The start is deliberately off: camera 2's rotation 1 degree
and its translation direction 5 degrees away from the truth, |t| = 1 as ``findM2`` gives, and
the points triangulated from that camera.

- ``rodriguesResidual`` must return the handout's residuals, in the handout's layout (or their
  negatives), at the start of each problem and at a perturbed x.
- ``bundleAdjustment``'s result is scored by the reprojection error recomputed here from the
  returned M2 and w: full marks within 2 % of the optimum (the reference's, or a gauge-fixed
  Levenberg-Marquardt solve made here, whichever is lower), partial credit on a log scale from
  the start.  A result whose |t| collapsed below a fifth of the start's scores nothing: the
  scale is not observable, and a vanishing baseline is a degenerate answer.
- M2 must hold a rotation, and o1, o2 the errors before and after.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.optimize

from autograder.results import QuestionResult
from autograder.sandbox import Call
from starter.checks.mistakes import (
    ba_mistakes,
    error_not_sum_of_squares,
    mistake,
    residual_layout,
)

from ._common import (
    Malformed,
    Outcome,
    as_array,
    as_number,
    first_problem,
    fmt,
    graded,
    log_score,
    parts,
)
from .hidden import Scenes, project

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


def total_error(K1, K2, p1, p2, M2, w) -> float:
    """Sum of squared reprojection distances in both images (pixels^2); inf when not finite."""
    r1 = p1 - project(K1 @ _M1, w)
    r2 = p2 - project(K2 @ M2, w)
    total = float(np.sum(r1 ** 2) + np.sum(r2 ** 2))
    return total if np.isfinite(total) else float("inf")


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


def _packing_mistake(r, inp) -> object:
    """The x_packing Mistake when r equals the reference residual of x read in another order."""
    from solutions import rodriguesResidual

    K1, M1, p1, K2, p2, x = inp
    n = len(p1)
    w, rest = x[:3 * n], x[3 * n:]
    orders = {
        "[r2, t2, w]": np.concatenate([x[6:], x[:3], x[3:6]]),
        "[t2, r2, w]": np.concatenate([x[6:], x[3:6], x[:3]]),
        "[w, t2, r2]": np.concatenate([w, rest[3:], rest[:3]]),
    }
    for order, x_read in orders.items():
        e = rodriguesResidual(K1, M1, p1, K2, p2, x_read)
        if min(np.abs(r - e).max(), np.abs(r + e).max()) <= 1e-6 * max(1.0, np.abs(e).max()):
            return mistake("x_packing", f"your residuals are those of x read as {order}")
    return None


def _judge_residuals(p: Prepared, outcomes):
    items = Outcome(outcomes.get("Q5:rodriguesResidual"), "rodriguesResidual").items(len(p.residual_inputs))
    right, lines, mistakes = 0, [], []
    for k, (inp, e, item) in enumerate(zip(p.residual_inputs, p.residual_expected, items), start=1):
        try:
            if not item.ok:
                raise Malformed(item.error)
            value = item.value.reshape(-1) if isinstance(item.value, np.ndarray) else item.value
            r = as_array(value, (None,), "the residuals")
            if r.shape != e.shape:
                raise Malformed(f"the residuals should be a vector of 4N = {e.size} values, got {r.size}")
        except Malformed as exc:
            lines.append(f"input {k}: {exc}")
            continue
        gap = min(np.abs(r - e).max(), np.abs(r + e).max()) if np.all(np.isfinite(r)) else np.inf
        tol = 1e-6 * max(1.0, float(np.abs(e).max()))
        ok = gap <= tol
        right += ok
        lines.append(f"input {k}: largest difference from the handout's residuals {fmt(gap)} px "
                     f"(goal <= {tol:.1g} px)")
        if not ok and np.all(np.isfinite(r)):
            mistakes += [m for m in (residual_layout(r, e), _packing_mistake(r, inp)) if m]
    return graded("rodriguesResidual returns the handout's residuals", 6, right / len(items), lines, mistakes)


def _judge_ba(p: Prepared, outcomes):
    items = Outcome(outcomes.get("Q5:bundleAdjustment"), "bundleAdjustment").items(len(p.problems))
    opt_tests, rot_ok, rep_ok = [], [], []
    rot_lines, rep_lines, rep_mistakes = [], [], []
    for pr, item in zip(p.problems, items):
        lines, mistakes, fraction = [], [], 0.0
        goal = 1.02 * pr.optimum + 0.05
        try:
            if not item.ok:
                raise Malformed(item.error)
            M2, w, o1, o2 = parts(item.value, 4, "bundleAdjustment")
            M2 = as_array(M2, (3, 4), "M2")
            w = as_array(w, (len(pr.p1), 3), "w")
        except Malformed as exc:
            lines.append(f"{pr.label}: {exc}")
            opt_tests.append(graded(f"bundle adjustment on {pr.label}", 5, 0.0, lines))
            rot_ok.append(False)
            rep_ok.append(False)
            continue
        err = total_error(pr.K1, pr.K2, pr.p1, pr.p2, M2, w)
        t0, t1 = np.linalg.norm(pr.M2_init[:, 3]), np.linalg.norm(M2[:, 3])
        collapsed = not (np.isfinite(t1) and t1 >= 0.2 * t0)
        fraction = 0.0 if collapsed else log_score(err, pr.start, goal)
        lines.append(f"{pr.label}: reprojection error of your M2 and w {fmt(err)} px^2 (start {fmt(pr.start)}, "
                     f"goal <= {fmt(goal)} px^2)")
        if collapsed:
            lines.append(f"|t| went from {fmt(t0)} to {fmt(t1)}: the reconstruction collapsed")
            mistakes.append(mistake("ba_scale_collapse", f"|t| went from {t0:.3g} to {t1:.3g}"))
        elif err >= pr.start * (1 - 1e-6):
            mistakes.append(mistake("ba_not_decreasing", f"start {pr.start:.6g}, result {err:.6g}"))
        opt_tests.append(graded(f"bundle adjustment on {pr.label}", 5, fraction, lines, mistakes))
        R = M2[:, :3]
        is_rot = bool(np.all(np.isfinite(R)) and np.allclose(R.T @ R, np.eye(3), atol=1e-6) and np.linalg.det(R) > 0)
        rot_ok.append(is_rot)
        rot_lines.append(f"{pr.label}: M2[:, :3] is {'' if is_rot else 'not '}a rotation")
        try:
            o1v, o2v = as_number(o1, "o1"), as_number(o2, "o2")
        except Malformed as exc:
            rep_ok.append(False)
            rep_lines.append(f"{pr.label}: {exc}")
            continue
        good = bool(np.isclose(o1v, pr.start, rtol=1e-3) and np.isclose(o2v, err, rtol=1e-3, atol=1e-6))
        rep_ok.append(good)
        rep_lines.append(f"{pr.label}: o1 = {fmt(o1v)} and o2 = {fmt(o2v)}; your start and result give "
                         f"{fmt(pr.start)} and {fmt(err)} px^2")
        if good:
            continue
        if err >= pr.start * (1 - 1e-6) and o2v < err:
            # A lower o2 than what the returned M2 and w give: the result returned is the start.
            rep_mistakes.append(mistake("ba_not_decreasing", f"you report o2 = {o2v:.6g}, but the M2 and w you "
                                                              f"return give {err:.6g}, the start's error"))
            continue
        rep_mistakes += ba_mistakes(o1v, o2v, pr.M2_init[:, 3], M2[:, 3])
        r1 = pr.p1 - project(pr.K1 @ _M1, w)
        r2 = pr.p2 - project(pr.K2 @ M2, w)
        if np.all(np.isfinite(r1)) and np.all(np.isfinite(r2)):
            rep_mistakes += [m for m in (error_not_sum_of_squares(o2v, r1, r2),) if m]
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
