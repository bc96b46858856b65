"""Q2: ``eightpoint(pts1, pts2, M)`` on hidden scenes, judged by judging.fundamental.

F is defined up to scale and sign, and several answers are right (refineF or not, the handout's
1/M scaling or Hartley's normalisation), so no F is compared entry by entry.  Instead the RMS
symmetric distance of *true* matches to the student's epipolar lines must stay below a goal set
from the valid variants; F must have rank 2; noise-free matches must give an exact F (which also
lets the catalogue name what went wrong), also with refineF switched off inside the sandbox (every
global of eightpoint bound to refineF returns its F unchanged for that one call), so that an F
refineF polished into a near miss (a transposed design matrix) is seen as written; the data files' uint16 points must give the F of the
same points as float.  Rank 2 and uint16 count only where F fits the scene: a zero or constant
matrix earns nothing.
"""

from __future__ import annotations

import numpy as np
import pytest

from autograder.hidden.cases import SECONDS
from autograder.hidden.feedback import value_of
from judging import fundamental as jf
from judging.verdict import Malformed


@pytest.fixture(scope="session")
def fundamental(hidden):
    """The prepared inputs (``autograder.hidden.cases.fundamental.Fundamental``)."""
    return hidden.prepared["fundamental"]


@pytest.fixture(scope="session")
def eightpoint_F(student, fundamental) -> dict:
    """The student's F (or the Malformed saying why there is none) of every case, by case: one request."""
    p = fundamental
    cases = (*p.cases, p.exact, p.uint16)
    outcomes = student.each("eightpoint", [(c.pts1, c.pts2, c.M) for c in cases], seconds=SECONDS["eightpoint"],
                            slack=5 * student.time_scale + 2)
    out = {}
    for case, o in zip(cases, outcomes):
        try:
            out[case] = jf.read_F(value_of("eightpoint", o))
        except Malformed as exc:
            out[case] = exc
    return out


@pytest.fixture(scope="session")
def eightpoint_fits(fundamental, eightpoint_F) -> dict:
    """judging.fundamental.fit of every scene's F (judged once for the checks that need it), by case."""
    return {c: jf.fit(eightpoint_F[c], c.eval1, c.eval2, c.goal, c.M)
            for c in fundamental.cases if not isinstance(eightpoint_F[c], Malformed)}


@pytest.fixture(scope="session")
def eightpoint_exact(fundamental, eightpoint_F):
    """judging.fundamental.exact_fit of the noise-free matches' F, or the Malformed."""
    F = eightpoint_F[fundamental.exact]
    return F if isinstance(F, Malformed) else jf.exact_fit(F, fundamental.exact.eval1, fundamental.exact.eval2,
                                                           fundamental.exact.M)


@pytest.fixture(scope="session")
def eightpoint_exact_off(student, fundamental):
    """judging.fundamental.exact_fit of the noise-free matches' F with refineF switched off, or the Malformed."""
    c = fundamental.exact
    o = student.each("eightpoint", [(c.pts1, c.pts2, c.M)], seconds=SECONDS["eightpoint"],
                     slack=5 * student.time_scale + 2, swap={"refineF": "identity"})[0]
    try:
        F = jf.read_F(value_of("eightpoint", o))
    except Malformed as exc:
        return exc
    return jf.exact_fit(F, c.eval1, c.eval2, c.M)


@pytest.mark.points(5, question="Q2", name="F fits the true matches of every scene")
def test_F_fits_the_true_matches(fundamental, eightpoint_F, eightpoint_fits, eightpoint_exact, eightpoint_exact_off,
                                 score):
    lines, mistakes = [], []
    for case in fundamental.cases:
        v = eightpoint_fits.get(case)
        if v is None:
            lines.append(f"{case.label}: {eightpoint_F[case]}")
            continue
        mistakes += v.mistakes
        lines.append(f"{case.label}: {v.sentence}{'' if v.passed else ': too far'}")
    exact = [] if isinstance(eightpoint_exact, Malformed) else list(eightpoint_exact.mistakes)
    if not exact and not isinstance(eightpoint_exact_off, Malformed):
        exact = list(eightpoint_exact_off.mistakes)
    right = sum(v.passed for v in eightpoint_fits.values())
    score.grade(right / len(fundamental.cases), lines, exact or mistakes)


@pytest.mark.points(2, question="Q2", name="F has rank 2 (counted where F fits)")
def test_F_has_rank_2(fundamental, eightpoint_F, eightpoint_fits, score):
    right, lines, mistakes = 0, [], []
    for case in fundamental.cases:
        fit = eightpoint_fits.get(case)
        if fit is None:
            continue
        r = jf.rank_two(eightpoint_F[case], case.M)
        mistakes += r.mistakes
        right += r.passed and fit.passed
        lines.append(f"{case.label}: {r.measured}" + ("" if fit.passed or not r.passed else
                                                      ", but F does not fit the scene"))
    if not lines:
        lines.append(next((str(F) for F in eightpoint_F.values() if isinstance(F, Malformed)), "no F to check"))
    score.grade(right / len(fundamental.cases), lines, mistakes)


@pytest.mark.points(2, question="Q2", name="noise-free matches give an exact F")
def test_noise_free_matches_give_an_exact_F(eightpoint_exact, eightpoint_exact_off, score):
    if isinstance(eightpoint_exact, Malformed):
        score.grade(0.0, [str(eightpoint_exact)])
    off = eightpoint_exact_off
    if isinstance(off, Malformed):
        score.grade(0.0, [eightpoint_exact.sentence, f"with refineF switched off: {off}"])
    lines = [eightpoint_exact.sentence, f"with refineF switched off: {off.sentence}"]
    mistakes = eightpoint_exact.mistakes or off.mistakes
    score.grade(float(eightpoint_exact.passed and off.passed), lines, mistakes)


@pytest.mark.points(1, question="Q2", name="the data files' uint16 points work as well as float ones")
def test_uint16_points_work_as_float_ones(fundamental, eightpoint_F, eightpoint_fits, score):
    u16 = fundamental.uint16
    base = next(c for c in fundamental.cases if c.label == u16.label.rsplit(",", 1)[0])
    F16 = eightpoint_F[u16]
    if isinstance(F16, Malformed):
        score.grade(0.0, [str(F16)])
    fit = eightpoint_fits.get(base)
    # Like rank 2, this counts only for an F of the scene: a constant answer is the same for any input.
    v = jf.uint16_same(F16, eightpoint_F[base] if fit is not None else np.zeros((3, 3)))
    fits = fit is not None and fit.passed
    score.grade(float(v.passed and fits), [f"{u16.label}: {v.sentence}" + (
        "" if fits else ", but the F of the float points does not fit")], v.mistakes)
