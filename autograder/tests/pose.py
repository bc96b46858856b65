"""Q3.3: ``findM2(F, pts1, pts2, K1, K2) -> (M2, C2, w)``: the right camera of the four.

E fixes camera 2 up to the four candidates of ``camera2`` and the scale of t, so M2 is compared
with the right candidate by rotation angle and direction of t only.  The right candidate is the
one nearest the true pose (the reference's choice on the official data, which has no truth).
Inputs: an exact scene with K1 != K2 and its true F, and hidden scenes with the F the reference
estimates from their noisy matches.  C2 must be K2 M2, and w the points triangulated with it.
Every verdict is judging.pose's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from autograder.results import QuestionResult
from autograder.hidden.legacy import Call
from judging import pose as jp
from judging.pose import pose_gap
from judging.verdict import Malformed

from ._common import Outcome, first_problem, graded
from .hidden import Scenes

__all__ = ["FUNCTIONS", "QUESTIONS", "calls", "judge", "pose_gap", "prepare"]

QUESTIONS = ("Q3.3",)
FUNCTIONS = ("findM2",)
_CALL = "Q3.3:findM2"
_SECONDS_PER_CALL = 5.0
_M1 = np.hstack([np.eye(3), np.zeros((3, 1))])


@dataclass(frozen=True, eq=False)
class Case:
    label: str
    F: np.ndarray
    pts1: np.ndarray
    pts2: np.ndarray
    K1: np.ndarray
    K2: np.ndarray
    right: np.ndarray    # (3, 4) the right candidate


@dataclass(frozen=True, eq=False)
class Prepared:
    cases: tuple[Case, ...]


def _nearest(candidates: np.ndarray, truth: np.ndarray) -> np.ndarray:
    gaps = [max(pose_gap(candidates[:, :, i], truth)) for i in range(candidates.shape[2])]
    return candidates[:, :, int(np.argmin(gaps))]


def prepare(scenes: Scenes) -> Prepared:
    from solutions import eightpoint, essentialMatrix, findM2
    from starter import camera2

    tv = scenes.two_view
    cases = [Case("noise-free matches", tv.F, tv.pts1, tv.pts2, tv.K1, tv.K2, tv.M2)]
    for tc in [scenes.hidden[0], *([scenes.official] if scenes.official else [])]:
        F = eightpoint(tc.pts1, tc.pts2, tc.M)
        if tc.has_truth:
            right = _nearest(camera2(essentialMatrix(F, tc.K1, tc.K2)), tc.scene.M2)
        else:
            right = findM2(F, tc.pts1, tc.pts2, tc.K1, tc.K2)[0]
        cases.append(Case(tc.label, F, tc.pts1, tc.pts2, tc.K1, tc.K2, right))
    return Prepared(tuple(cases))


def calls(p: Prepared, time_scale: float) -> list[Call]:
    items = [((c.F, c.pts1, c.pts2, c.K1, c.K2), {}) for c in p.cases]
    budget = _SECONDS_PER_CALL * len(items) * time_scale
    return [Call(_CALL, "__hw4_each", ("findM2", items, budget), timeout=budget + 2)]


def judge(p: Prepared, outcomes) -> list[QuestionResult]:
    from solutions import triangulate

    items = Outcome(outcomes.get(_CALL), "findM2").items(len(p.cases))
    right, lines, mistakes = 0, [], []
    consistent, cons_lines = 0, []
    for case, item in zip(p.cases, items):
        try:
            if not item.ok:
                raise Malformed(item.error)
            M2, C2, w = jp.read_findM2(item.value, len(case.pts1))
        except Malformed as exc:
            lines.append(f"{case.label}: {exc}")
            continue
        v = jp.right_camera(M2, case.right)
        right += v.passed
        lines.append(f"{case.label}: {v.sentence}")
        mistakes += v.mistakes
        linear_err = np.inf
        if np.all(np.isfinite(M2)):
            with np.errstate(all="ignore"):
                linear_err = triangulate(case.K1 @ _M1, case.pts1, case.K2 @ M2, case.pts2)[1]
        c = jp.outputs(M2, C2, w, case.K1, case.K2, case.pts1, case.pts2, linear_err)
        consistent += c.passed
        mistakes += c.mistakes
        cons_lines.append(f"{case.label}: {c.sentence}")
    n = len(p.cases)
    if not cons_lines:
        cons_lines.append(first_problem(items) or "no result to check")
    tests = [
        graded("M2 is the camera that puts the points in front of both cameras", 8, right / n, lines, mistakes),
        graded("C2 = K2 M2 and w are the points triangulated with it", 2, consistent / n, cons_lines, mistakes),
    ]
    return [QuestionResult.of("Q3.3", tests)]
