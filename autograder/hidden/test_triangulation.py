"""Q3.2: ``triangulate(C1, pts1, C2, pts2) -> (w, err)``, judged by judging.triangulation.

- Exact matches of an exact scene (K1 != K2) must give back the true points.
- On noisy matches with the true cameras (the official data: the reference's cameras), the
  reprojection error of the student's points, recomputed here, must be within 20 % of the
  reference's linear triangulation (a better method, e.g. optimal triangulation, is welcome).
- ``err`` must be the total squared reprojection error of the points returned (both images).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from autograder.inputs.cases import SECONDS
from autograder.feedback.words import read_returned
from judging import triangulation as jt
from judging.verdict import Malformed, Verdict, figure_text


@dataclass(frozen=True)
class Triangulated:
    """One case's result: the student's w and err, the points' verdict and err's, or why there are none."""

    problem: Malformed | None = None
    w: np.ndarray | None = None
    points: Verdict | None = None
    err: Verdict | None = None


@pytest.fixture(scope="session")
def triangulation(hidden):
    """The prepared inputs (``autograder.inputs.triangulation.Triangulation``)."""
    return hidden.prepared["triangulation"]


@pytest.fixture(scope="session")
def triangulated(student, triangulation) -> dict:
    """Every case's ``Triangulated``, by case (the exact one first): one request, each judged once."""
    cases = triangulation.all
    inputs = [(c.C1, c.pts1, c.C2, c.pts2) for c in cases]
    outcomes = student.each("triangulate", inputs, seconds=SECONDS["triangulate"])
    out = {}
    for case, args, o in zip(cases, inputs, outcomes):
        try:
            w, err = read_returned("triangulate", o, lambda v, n=len(case.pts1): jt.read_w_err(v, n), args)
        except Malformed as exc:
            out[case] = Triangulated(exc)
            continue
        if case is triangulation.exact:
            v = jt.exact_points(w, case.X, case.M2)
        else:
            v = jt.noisy_error(w, case.C1, case.pts1, case.C2, case.pts2, case.linear_err, case.M2)
        out[case] = Triangulated(None, w, v, jt.err_reported(err, w, case.C1, case.pts1, case.C2, case.pts2))
    return out


def _point_mistakes(triangulated) -> list:
    return [m for t in triangulated.values() if t.points is not None for m in t.points.mistakes]


@pytest.mark.points(3, question="Q3.2", name="noise-free matches give the true points")
def test_noise_free_matches_give_the_true_points(triangulation, triangulated, score):
    t = triangulated[triangulation.exact]
    label = triangulation.exact.label
    if t.problem is not None:
        score.grade(0.0, [f"{label}: {t.problem}"])
    score.grade(float(t.points.passed), [f"{label}: {t.points.sentence}"], _point_mistakes(triangulated))


@pytest.mark.points(4, question="Q3.2", name="noisy matches: reprojection error as low as linear triangulation's")
def test_noisy_matches_reproject_as_well_as_linear_triangulation(triangulation, triangulated, score):
    lines, right = [], 0
    for case in triangulation.noisy:
        t = triangulated[case]
        if t.problem is not None:
            lines.append(f"{case.label}: {t.problem}")
            continue
        right += t.points.passed
        lines.append(f"{case.label}: {t.points.sentence}")
    score.grade(right / len(triangulation.noisy), lines, _point_mistakes(triangulated))


@pytest.mark.points(3, question="Q3.2", name="err is the total squared reprojection error of w")
def test_err_is_the_total_squared_reprojection_error(triangulated, score):
    judged = [(case, t) for case, t in triangulated.items() if t.err is not None]
    lines, mistakes = [], []
    for case, t in judged:
        if not t.err.passed:
            mistakes += t.err.mistakes
            lines.append(f"{case.label}: " + figure_text(False, f"{t.err.measured}, but your points give "
                                                                f"{t.err.goal.split(' from')[0]} px^2"))
    if not judged:
        problem = next((t.problem for t in triangulated.values() if t.problem is not None), None)
        score.grade(0.0, [str(problem) if problem else "no (w, err) to check"])
    if len(lines) == 0:
        lines.append("err is the sum of squared distances in both images")
    score.grade(sum(t.err.passed for _, t in judged) / len(triangulated), lines, mistakes)
