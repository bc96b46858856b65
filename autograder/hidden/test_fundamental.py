"""Q2: ``eightpoint(pts1, pts2, M)`` on hidden scenes, judged by judging.fundamental.

F is defined up to scale and sign, and several answers are right (refineF or not, the handout's
1/M scaling or Hartley's normalisation, SVD or eigh), so no F is compared entry by entry:

- fits: the RMS symmetric distance of *true* matches to the student's epipolar lines stays below a
  goal set from the scene's noise and the reference's distance on the same scene (FIT_FACTOR times
  the larger), for F as returned and for F with refineF switched off (the goal is FIT_FACTOR times
  the reference's distance without refineF at least, so every valid method meets it either way;
  a design matrix built for F transposed does not once refineF stops polishing it);
  The hidden scenes' cameras share K and turn little, so their F is nearly skew-symmetric and
  their matches cannot tell F from F transposed; each is therefore also given with camera 2's
  intrinsics changed (``autograder.inputs.fundamental._OTHER_K2``: zoomed out, principal point moved), where
  the transposed true F lies at least 1.5 goals off;
- rank 2, and the data files' uint16 points give the F of the same points as float: counted only
  where F fits the scene, as returned and with refineF off (a zero or constant matrix earns
  nothing, nor does a transposed F polished into fitting);
- noise-free matches (several scenes) give an exact F, to EXACT_TOL * M; the catalogue then names
  what went wrong.  This is the sharp test of the method, so it weighs most (4 of 10): refineF
  polishes a transposed F into fitting noisy matches.

Every input is given twice: as it is, and with refineF switched off inside the sandbox for that
request (``core.refine_switch``, the switch the public self-check throws too; the FAQ's "comment
out the call to refineF"): by every route (the kit's refineF by any name, ``starter.refineF``, a
default argument, an import inside eightpoint; a refineF of the student's own, such as
``helper.refineF``), refineF skips its minimisation and returns the closest rank-2 matrix to the F
it is given, unit norm, so that only the polish is gone.  Rank 2, the exact F and uint16 are
judged on both F's, since refineF polishes a transposed design matrix into a near miss.
A lost point's feedback says how eightpoint was called (argument kinds, never values).
"""

from __future__ import annotations

import numpy as np
import pytest

from autograder.inputs.cases import SECONDS
from autograder.feedback.words import called_as, read_returned
from judging import fundamental as jf
from judging.verdict import Malformed, Verdict, figure_text

_OFF = "with refineF switched off"
_OFF_NOTE = ("switched off: refineF skipped its minimisation and returned the closest rank-2 matrix to the F it was "
             "given (unit norm), as the FAQ's 'comment out the call to refineF' (refineF can hide a mistake made "
             "before it)")


@pytest.fixture(scope="session")
def fundamental(hidden):
    """The prepared inputs (``autograder.inputs.fundamental.Fundamental``)."""
    return hidden.prepared["fundamental"]


def _all_cases(p) -> tuple:
    return (*p.cases, *p.exact, p.uint16)


def _args(case) -> tuple:
    return case.pts1, case.pts2, case.M


def request_F(student, p, swap=None) -> dict:
    """The student's F (or the Malformed saying why there is none, and how eightpoint was called) of
    every case, by case: one request."""
    cases = _all_cases(p)
    outcomes = student.each("eightpoint", [_args(c) for c in cases], seconds=SECONDS["eightpoint"],
                            slack=5 * student.time_scale + 2, swap=swap)
    out = {}
    for case, o in zip(cases, outcomes):
        try:
            out[case] = read_returned("eightpoint", o, jf.read_F, _args(case))
        except Malformed as exc:
            out[case] = exc
    return out


@pytest.fixture(scope="session")
def eightpoint_F(student, fundamental) -> dict:
    """The F of every case as eightpoint returns it, by case."""
    return request_F(student, fundamental)


@pytest.fixture(scope="session")
def eightpoint_F_off(student, fundamental) -> dict:
    """The F of every case with refineF switched off inside the sandbox, by case."""
    return request_F(student, fundamental, {"refineF": "off"})


def _judge(judgment, F, *args):
    return F if isinstance(F, Malformed) else judgment(F, *args)


def _passed(v) -> bool:
    return not isinstance(v, Malformed) and v.passed


def _mistakes(*verdicts) -> list:
    return [m for v in verdicts if not isinstance(v, Malformed) for m in v.mistakes]


def _how_called(cases, *, off: bool = False) -> list[str]:
    """One line per kind of call among ``cases``: how eightpoint was called (argument kinds only)."""
    seen = dict.fromkeys(called_as("eightpoint", None, _args(c)) for c in cases)
    return [f"eightpoint was {call}" + (f", as given and {_OFF}" if off else "") for call in seen]


def judge_q2(p, F: dict, F_off: dict) -> dict:
    """The grade of each Q2 test: ``{"fits" | "rank" | "exact" | "uint16": (fraction, lines, mistakes)}``.

    p : the prepared inputs (``autograder.inputs.fundamental.Fundamental``); F, F_off : by case (``_all_cases``),
    the student's F (3, 3) or the Malformed saying why there is none, as returned and with refineF
    switched off.  Pure: the tests below and tests/judging_tests/test_fundamental_goals.py grade with it.
    """
    # Rank 2 and uint16 count where F fits as returned and with refineF off (a constant answer
    # earns nothing, nor does a transposed F that refineF polished into fitting).
    fits = {c: jf.fit(F[c], c.eval1, c.eval2, c.goal, c.M) for c in p.cases if not isinstance(F[c], Malformed)}
    fits_both = {c: _fit_both(c, v, F_off[c]) for c, v in fits.items()}
    exact = {c: (_judge(jf.exact_fit, F[c], c.eval1, c.eval2, c.M), _judge(jf.exact_fit, F_off[c], c.eval1, c.eval2, c.M))
             for c in p.exact}
    # The noise-free matches name a mistake best: as returned first, then with refineF off.
    named = _mistakes(*(on for on, _ in exact.values())) or _mistakes(*(off for _, off in exact.values()))
    return {"fits": _fits(p, F, fits_both, named), "rank": _rank(p, F, F_off, fits_both), "exact": _exact(exact, named),
            "uint16": _uint16(p, F, F_off, fits_both)}


def _fit_both(case, on, F_off):
    """``on`` (the ``jf.fit`` of F as returned), unless it passes and F with refineF off does not (or
    is malformed): then a failed verdict saying so."""
    if not on.passed:
        return on
    if isinstance(F_off, Malformed):
        return Verdict.of(on.what, False, f"{_OFF}: {F_off}", on.goal)
    off = jf.fit(F_off, case.eval1, case.eval2, case.goal, case.M)
    if off.passed:
        return on
    return Verdict.of(on.what, False, f"{on.measured} as returned, {off.measured} {_OFF}", off.goal, off.mistakes,
                      because=f"too far {_OFF}")


def _fits(p, F, fits, named):
    lines, mistakes, judged_wrong = [], [], []
    for case in p.cases:
        v = fits.get(case)
        if v is None:
            lines.append(f"{case.label}: {F[case]}")
            continue
        mistakes += v.mistakes
        if not v.passed:
            judged_wrong.append(case)
        lines.append(f"{case.label}: {v.sentence}")
    right = sum(v.passed for v in fits.values())
    return right / len(p.cases), lines + _how_called(judged_wrong), named or mistakes


def _rank(p, F, F_off, fits):
    right, lines, mistakes, judged_wrong = 0, [], [], []
    for case in p.cases:
        fit = fits.get(case)
        if fit is None:
            continue
        on = jf.rank_two(F[case], case.M)
        off = _judge(jf.rank_two, F_off[case], case.M)
        mistakes += _mistakes(on, off)
        ok = on.passed and _passed(off)
        right += ok and fit.passed
        text = on.measured
        if not _passed(off):
            text += f"; {_OFF}: {off if isinstance(off, Malformed) else off.measured}"
        # Rank 2 counts only where F fits: a rank that is right says which part failed instead.
        text = f"{case.label}: " + figure_text(ok and fit.passed, text, "",
                                               "F does not fit the scene" if ok and not fit.passed else "")
        if not ok:
            judged_wrong.append(case)
        lines.append(text)
    if not lines:
        lines.append(next((str(v) for v in F.values() if isinstance(v, Malformed)), "no F to check"))
    return right / len(p.cases), lines + _how_called(judged_wrong, off=True), mistakes


def _exact(exact, named):
    right, lines, judged_wrong = 0, [], []
    for case, (on, off) in exact.items():
        right += _passed(on) and _passed(off)
        for v, how in ((on, ""), (off, f", {_OFF}")):
            if isinstance(v, Malformed):
                lines.append(f"{case.label}{how}: {v}")
            elif not v.passed or not how:
                lines.append(f"{case.label}{how}: {v.sentence}")
                judged_wrong += [] if v.passed else [case]
    if not all(_passed(off) for _, off in exact.values()):
        lines.append(f"refineF was {_OFF_NOTE}")
    return right / len(exact), lines + _how_called(judged_wrong, off=True), named


def _uint16(p, F, F_off, fits):
    u16, twin = p.uint16, p.float_twin()
    fit = fits.get(twin)
    lines, verdicts = [], []
    for Fs, how in ((F, ""), (F_off, f", {_OFF}")):
        if isinstance(Fs[u16], Malformed):
            lines.append(f"{u16.label}{how}: {Fs[u16]}")
            continue
        # Like rank 2, this counts only for an F of the scene: a constant answer is the same for any input.
        usable = fit is not None and not isinstance(Fs[twin], Malformed)
        v = jf.uint16_same(Fs[u16], Fs[twin] if usable else np.zeros((3, 3)))
        verdicts.append(v)
        # The same F from uint16 counts only where the float F fits: then that is the part that failed.
        lines.append(f"{u16.label}{how}: " + (v.sentence if not v.passed or (fit is not None and fit.passed) else
                                              f"{v.what}: " + figure_text(False, v.measured, v.goal,
                                                                          "the F of the float points does not fit")))
    fits_too = fit is not None and fit.passed
    ok = len(verdicts) == 2 and all(v.passed for v in verdicts) and fits_too
    if not fits_too:
        lines.append(f"{twin.label}: the F of the float points does not fit, so uint16 earns nothing either")
    if not ok:
        lines += _how_called([u16, twin], off=True)
    return float(ok), lines, _mistakes(*verdicts)


@pytest.fixture(scope="session")
def q2(fundamental, eightpoint_F, eightpoint_F_off) -> dict:
    """``judge_q2`` of the student's F's: every Q2 test's grade, judged once."""
    return judge_q2(fundamental, eightpoint_F, eightpoint_F_off)


@pytest.mark.points(3, question="Q2", name="F fits the true matches of every scene")
def test_F_fits_the_true_matches(q2, score):
    score.grade(*q2["fits"])


@pytest.mark.points(2, question="Q2", name="F has rank 2 (counted where F fits)")
def test_F_has_rank_2(q2, score):
    score.grade(*q2["rank"])


@pytest.mark.points(4, question="Q2", name="noise-free matches give an exact F")
def test_noise_free_matches_give_an_exact_F(q2, score):
    score.grade(*q2["exact"])


@pytest.mark.points(1, question="Q2", name="the data files' uint16 points work as well as float ones")
def test_uint16_points_work_as_float_ones(q2, score):
    score.grade(*q2["uint16"])
