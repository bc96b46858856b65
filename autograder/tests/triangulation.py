"""Q3.2: ``triangulate(C1, pts1, C2, pts2) -> (w, err)``.

- Exact matches of an exact scene (K1 != K2) must give back the true points.
- On noisy matches with the true cameras (the official data: the reference's cameras), the
  reprojection error of the student's points, recomputed here, must be within 5 % of the
  reference's linear triangulation (a better method, e.g. optimal triangulation, is welcome).
- ``err`` must be the total squared reprojection error of the points returned (both images).
Every verdict is judging.triangulation's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from autograder.results import QuestionResult
from autograder.hidden.legacy import Call
from judging import triangulation as jt
from judging.verdict import Malformed

from ._common import Outcome, first_problem, graded
from .hidden import Scenes

__all__ = ["FUNCTIONS", "QUESTIONS", "calls", "judge", "prepare"]

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
    goal: float              # the reference's (linear) triangulation error on the noisy cases
    X: np.ndarray | None = None   # true points (exact case)


@dataclass(frozen=True, eq=False)
class Prepared:
    exact: Case
    noisy: tuple[Case, ...]


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
        noisy.append(Case(tc.label, C1, tc.pts1, C2, tc.pts2, M2, err))
    return Prepared(exact, tuple(noisy))


def calls(p: Prepared, time_scale: float) -> list[Call]:
    items = [((c.C1, c.pts1, c.C2, c.pts2), {}) for c in (p.exact, *p.noisy)]
    budget = _SECONDS_PER_CALL * len(items) * time_scale
    return [Call(_CALL, "__hw4_each", ("triangulate", items, budget), timeout=budget + 2)]


def read_w_err(item, n: int) -> tuple[np.ndarray, object]:
    """(w (n, 3), err as returned) from a triangulate record, or Malformed."""
    if not item.ok:
        raise Malformed(item.error)
    return jt.read_w_err(item.value, n)


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
        if case is p.exact:
            v = jt.exact_points(w, case.X, case.M2)
            exact_ok = v.passed
            exact_lines.append(f"{case.label}: {v.sentence}")
        else:
            v = jt.noisy_error(w, case.C1, case.pts1, case.C2, case.pts2, case.goal, case.M2)
            noisy_right += v.passed
            noisy_lines.append(f"{case.label}: {v.sentence}")
        geo_mistakes += v.mistakes
        err_total += 1
        e = jt.err_reported(err, w, case.C1, case.pts1, case.C2, case.pts2)
        if e.passed:
            err_right += 1
        else:
            err_mistakes += e.mistakes
            err_lines.append(f"{case.label}: {e.measured}, but your points give {e.goal.split(' from')[0]} px^2")
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
