"""Q3.2: ``triangulate(C1, pts1, C2, pts2) -> (w, err)``.

- Exact matches of an exact scene (K1 != K2) must give back the true points.
- On noisy matches with the true cameras (the official data: the reference's cameras), the
  reprojection error of the student's points, recomputed here, must be within 5 % of the
  reference's linear triangulation (a better method, e.g. optimal triangulation, is welcome).
- ``err`` must be the total squared reprojection error of the points returned (both images).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from autograder.results import QuestionResult
from autograder.sandbox import Call
from starter.checks.mistakes import error_not_sum_of_squares, points_behind_cameras

from ._common import (
    Malformed,
    Outcome,
    as_array,
    as_number,
    first_problem,
    fmt,
    graded,
    parts,
)
from .hidden import Scenes, project

__all__ = ["FUNCTIONS", "QUESTIONS", "calls", "judge", "prepare", "reprojection_residuals"]

QUESTIONS = ("Q3.2",)
FUNCTIONS = ("triangulate",)
_CALL = "Q3.2:triangulate"
_SECONDS_PER_CALL = 3.0
_M1 = np.hstack([np.eye(3), np.zeros((3, 1))])


@dataclass(frozen=True, eq=False)
class Case:
    label: str
    C1: np.ndarray
    pts1: np.ndarray
    C2: np.ndarray
    pts2: np.ndarray
    M2: np.ndarray
    goal: float              # largest accepted total squared reprojection error (noisy cases)
    X: np.ndarray | None = None   # true points (exact case)


@dataclass(frozen=True, eq=False)
class Prepared:
    exact: Case
    noisy: tuple[Case, ...]


def reprojection_residuals(C1, pts1, C2, pts2, w) -> tuple[np.ndarray, np.ndarray]:
    """x - proj(C, w) in image 1 and image 2, each (N, 2)."""
    return pts1 - project(C1, w), pts2 - project(C2, w)


def prepare(scenes: Scenes) -> Prepared:
    from solutions import eightpoint, findM2, triangulate

    tv = scenes.two_view
    exact = Case("noise-free matches", tv.C1, tv.pts1, tv.C2, tv.pts2, tv.M2, 0.0, tv.X)
    noisy = []
    for tc in [*scenes.hidden, *([scenes.official] if scenes.official else [])]:
        C1 = tc.K1 @ _M1
        if tc.has_truth:
            M2 = tc.scene.M2
        else:
            M2 = findM2(eightpoint(tc.pts1, tc.pts2, tc.M), tc.pts1, tc.pts2, tc.K1, tc.K2)[0]
        C2 = tc.K2 @ M2
        _, err = triangulate(C1, tc.pts1, C2, tc.pts2)
        noisy.append(Case(tc.label, C1, tc.pts1, C2, tc.pts2, M2, 1.05 * err + 1e-6))
    return Prepared(exact, tuple(noisy))


def calls(p: Prepared, time_scale: float) -> list[Call]:
    items = [((c.C1, c.pts1, c.C2, c.pts2), {}) for c in (p.exact, *p.noisy)]
    budget = _SECONDS_PER_CALL * len(items) * time_scale
    return [Call(_CALL, "__hw4_each", ("triangulate", items, budget), timeout=budget + 2)]


def read_w_err(item, n: int) -> tuple[np.ndarray, object]:
    """(w (n, 3), err as returned) from a triangulate record, or Malformed."""
    if not item.ok:
        raise Malformed(item.error)
    w, err = parts(item.value, 2, "triangulate")
    return as_array(w, (n, 3), "w"), err


def judge(p: Prepared, outcomes) -> list[QuestionResult]:
    cases = (p.exact, *p.noisy)
    items = Outcome(outcomes.get(_CALL), "triangulate").items(len(cases))
    exact_ok, exact_lines = False, []
    noisy_right, noisy_lines = 0, []
    err_right, err_total, err_lines = 0, 0, []
    geo_mistakes, err_mistakes = [], []
    for case, item in zip(cases, items):
        try:
            w, err = read_w_err(item, len(case.pts1))
        except Malformed as exc:
            (exact_lines if case is p.exact else noisy_lines).append(f"{case.label}: {exc}")
            continue
        res1, res2 = reprojection_residuals(case.C1, case.pts1, case.C2, case.pts2, w)
        total = float(np.sum(res1 ** 2) + np.sum(res2 ** 2)) if np.all(np.isfinite(w)) else float("inf")
        if case is p.exact:
            gap = float(np.max(np.abs(w - case.X))) if np.all(np.isfinite(w)) else float("inf")
            tol = 1e-6 * max(1.0, float(np.abs(case.X).max()))
            exact_ok = gap <= tol
            exact_lines.append(f"{case.label}: largest distance of your points from the true ones {fmt(gap)} "
                               f"(goal <= {tol:.1g})")
        else:
            ok = total <= case.goal
            noisy_right += ok
            noisy_lines.append(f"{case.label}: total squared reprojection error of your points {fmt(total)} px^2 "
                               f"(goal <= {fmt(case.goal)} px^2)")
            if not ok:
                behind = points_behind_cameras(w, _M1, case.M2)
                geo_mistakes += [behind] if behind else []
        err_total += 1
        m = error_not_sum_of_squares(err, res1, res2)
        if m is None:
            err_right += 1
        else:
            err_mistakes.append(m)
            try:
                reported = fmt(as_number(err, "err"))
            except Malformed:
                reported = "not a number"
            err_lines.append(f"{case.label}: err = {reported}, but your points give {fmt(total)} px^2")
    if err_total == 0:
        err_lines.append(first_problem(items) or "no (w, err) to check")
    elif err_right == err_total:
        err_lines.append("err is the sum of squared distances in both images")
    tests = [
        graded("noise-free matches give the true points", 3, float(exact_ok), exact_lines, geo_mistakes),
        graded("noisy matches: reprojection error as low as linear triangulation's", 4,
               noisy_right / len(p.noisy), noisy_lines, geo_mistakes),
        graded("err is the total squared reprojection error of w", 3,
               err_right / len(cases) if err_total else 0.0, err_lines, err_mistakes),
    ]
    return [QuestionResult.of("Q3.2", tests)]
