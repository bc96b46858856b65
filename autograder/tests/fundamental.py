"""Q2: ``eightpoint(pts1, pts2, M)`` on hidden scenes, judged by epipolar distances of true matches.

F is defined up to scale and sign, and several answers are right (refineF or not, the handout's
1/M scaling or Hartley's normalisation), so no F is compared entry by entry.  Instead:

- on each scene, the RMS symmetric distance of *true* correspondences (noise-free, not the ones
  fitted) to the student's epipolar lines must stay below a goal set from the valid variants
  (the reference with and without refineF, and a Hartley-normalised fit made here):
  judging.fundamental.fit_goal.  A transposed or unscaled F misses by far more;
- F must have rank 2 (the handout requires it);
- noise-free matches must give an F that fits them (judging.fundamental.exact_fit); this answer
  also lets the mistake catalogue name what went wrong;
- the data files' uint16 points must give the same F as the same points as float.
Every verdict is judging.fundamental's (the public self-check's too).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from autograder.results import QuestionResult
from autograder.hidden.legacy import Call
from core.geometry import symmetric_epipolar_distances
from judging import fundamental as jf
from judging.verdict import Malformed
from starter.ransac import eightpoint_hartley

from ._common import Outcome, first_problem, graded
from .hidden import Scenes

__all__ = ["FUNCTIONS", "QUESTIONS", "calls", "judge", "prepare"]

QUESTIONS = ("Q2",)
FUNCTIONS = ("eightpoint",)
_CALL = "Q2:eightpoint"
_SECONDS_PER_CALL = 5.0
_EXACT_TOL_PX = 0.05


@dataclass(frozen=True, eq=False)
class Case:
    """One eightpoint input: pts1, pts2 (N, 2), M; eval1, eval2 (P, 2) true matches; goal in px."""

    label: str
    pts1: np.ndarray
    pts2: np.ndarray
    M: float
    eval1: np.ndarray
    eval2: np.ndarray
    goal: float


@dataclass(frozen=True, eq=False)
class Prepared:
    cases: tuple[Case, ...]
    exact: Case
    uint16: Case


def _hartley(pts1, pts2):
    """F by the reference eight-point with Hartley's normalisation instead of 1/M (a valid variant)."""
    from solutions import eightpoint

    F = eightpoint_hartley(lambda a, b, M: eightpoint(a, b, M, refine=False), pts1, pts2)
    return F / np.linalg.norm(F)


def _rms(F, eval1, eval2) -> float:
    d = symmetric_epipolar_distances(F, eval1, eval2)
    return float(np.sqrt(np.mean(d ** 2)))


def _evaluation_matches(case) -> tuple[np.ndarray, np.ndarray]:
    if not case.has_truth:
        return case.pts1, case.pts2  # no ground truth: the given matches, as the handout uses them
    s = case.scene
    keep = s.visible2
    return np.column_stack([s.x1, s.y1]).astype(float)[keep], s.x2_true[keep]


def _case(label, pts1, pts2, M, eval1, eval2) -> Case:
    from solutions import eightpoint

    p1, p2 = np.asarray(pts1, float), np.asarray(pts2, float)
    variants = [eightpoint(p1, p2, M), eightpoint(p1, p2, M, refine=False), _hartley(p1, p2)]
    worst = max(_rms(F, eval1, eval2) for F in variants)
    return Case(label, pts1, pts2, float(M), eval1, eval2, jf.fit_goal([worst]))


def prepare(scenes: Scenes) -> Prepared:
    cases = []
    for tc in scenes.temple_cases():
        e1, e2 = _evaluation_matches(tc)
        cases.append(_case(tc.label, tc.pts1, tc.pts2, tc.M, e1, e2))
    base = scenes.default or scenes.hidden[-1]
    s = base.scene
    exact = Case("noise-free matches", s.pts1_true.copy(), s.pts2_true.copy(), float(s.M),
                 s.pts1_true, s.pts2_true, _EXACT_TOL_PX)
    e1, e2 = _evaluation_matches(base)
    ref = next(c for c in cases if c.label == base.label)
    uint16 = Case(f"{base.label}, as uint16", s.pts1.astype(np.uint16), s.pts2.astype(np.uint16), float(s.M),
                  e1, e2, ref.goal)
    return Prepared(tuple(cases), exact, uint16)


def calls(p: Prepared, time_scale: float) -> list[Call]:
    items = [((c.pts1, c.pts2, c.M), {}) for c in (*p.cases, p.exact, p.uint16)]
    budget = _SECONDS_PER_CALL * len(items) * time_scale
    return [Call(_CALL, "__hw4_each", ("eightpoint", items, budget), timeout=budget + 5 * time_scale + 2)]


def _F(item) -> np.ndarray:
    if not item.ok:
        raise Malformed(item.error)
    return jf.read_F(item.value)


def judge(p: Prepared, outcomes) -> list[QuestionResult]:
    out = Outcome(outcomes.get(_CALL), "eightpoint")
    n = len(p.cases)
    items = out.items(n + 2)
    fits, lines, rank_right, rank_lines = 0, [], 0, []
    rank_mistakes, fit_mistakes = [], []
    float_F, float_fits = {}, {}
    for case, item in zip(p.cases, items[:n]):
        try:
            F = _F(item)
        except Malformed as exc:
            lines.append(f"{case.label}: {exc}")
            continue
        float_F[case.label] = F
        v = jf.fit(F, case.eval1, case.eval2, case.goal, case.M)
        float_fits[case.label] = v.passed
        fits += v.passed
        fit_mistakes += v.mistakes
        lines.append(f"{case.label}: {v.sentence}{'' if v.passed else ': too far'}")
        # Rank counts only for an F of the scene: a zero or made-up rank-2 matrix earns nothing.
        r = jf.rank_two(F, case.M)
        rank_mistakes += r.mistakes
        rank_right += r.passed and v.passed
        rank_lines.append(f"{case.label}: {r.measured}" + ("" if v.passed or not r.passed else
                                                           ", but F does not fit the scene"))

    mistakes, exact_lines, exact_ok = [], [], False
    try:
        v = jf.exact_fit(_F(items[n]), p.exact.eval1, p.exact.eval2, p.exact.M)
        exact_ok, mistakes = v.passed, list(v.mistakes)
        exact_lines.append(v.sentence)
    except Malformed as exc:
        exact_lines.append(str(exc))

    u16_lines, u16_ok, u16_mistakes = [], False, []
    base_label = p.uint16.label.rsplit(",", 1)[0]
    try:
        F16 = _F(items[n + 1])
        if base_label in float_F:
            v = jf.uint16_same(F16, float_F[base_label])
        else:
            v = jf.uint16_same(F16, np.zeros((3, 3)))
        # Like rank 2, this counts only for an F of the scene: a constant answer is the same for any input.
        u16_ok, u16_mistakes = v.passed and float_fits.get(base_label, False), list(v.mistakes)
        u16_lines.append(f"{p.uint16.label}: {v.sentence}" + ("" if float_fits.get(base_label) else
                                                               ", but the F of the float points does not fit"))
    except Malformed as exc:
        u16_lines.append(str(exc))

    if not rank_lines:
        rank_lines.append(first_problem(items[:n]) or "no F to check")
    tests = [
        graded("F fits the true matches of every scene", 5, fits / n, lines, mistakes or fit_mistakes),
        graded("F has rank 2 (counted where F fits)", 2, rank_right / n, rank_lines, rank_mistakes),
        graded("noise-free matches give an exact F", 2, float(exact_ok), exact_lines, mistakes),
        graded("the data files' uint16 points work as well as float ones", 1, float(u16_ok), u16_lines,
               u16_mistakes),
    ]
    return [QuestionResult.of("Q2", tests)]
