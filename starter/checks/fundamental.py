"""Public check of Q2: ``eightpoint(pts1, pts2, M) -> F``; every verdict is judging.fundamental's."""

from __future__ import annotations

from judging import fundamental as jf
from judging.mistakes import mistake

from ._common import finish, read_or_report, run_failed, stop_if_not_implemented
from ._scenes import NoisyPair, default_temple, two_view
from .instrument import refineF_switched_off
from .report import CheckReport, Outcome, call

__all__ = ["check_eightpoint"]

_N_NOISY = 20
_OFF = "refineF switched off"


def _default_goal(M) -> float:
    # No reference runs here and the data's noise is unknown, so the goal is one that a valid
    # unrefined 1/M eight-point (the least accurate valid method) keeps: a share of M, but never
    # below 5 px (it reaches 2.9 px RMS on a 320x240 pair, where the share would be 2.5 px).
    return max(5.0, jf.DATA_GOAL * float(M))


def _switched_off(eightpoint):
    """eightpoint run with refineF switched off: returns (F, number of refineF calls)."""
    def run(pts1, pts2, M):
        return refineF_switched_off(eightpoint, pts1, pts2, M)
    run.__name__ = getattr(eightpoint, "__name__", "eightpoint")
    return run


def _off_value(out):
    """The switched-off run's Outcome with its F alone, and whether refineF was called."""
    if not out.ok:
        return out, False
    value, calls = out.value
    return (Outcome("ok", value) if value is not None else Outcome("not implemented")), calls > 0


def check_eightpoint(eightpoint, *, scene: NoisyPair | None = None, root=None, verbose: bool = True) -> CheckReport:
    """Run ``eightpoint`` on generated matches with a known F, and on the default data.

    Parameters
    ----------
    eightpoint : the student's function (pts1 (N, 2), pts2 (N, 2), M) -> F (3, 3), pixels
        (x, y) = (column, row), x2^T F x1 = 0.
    scene : the pair to check on (default: the public generated pair, 640 x 480, K1 != K2).
    root : data folder for the default data (default: data/ or $HW4_DATA).
    verbose : print the report.

    Checked (judging.fundamental): exact matches lie on the epipolar lines of F; on noisy
    matches (enlarged: every coordinate above 256) F has rank 2 and uint16 points give the same
    F as float points; on the default data the matches lie near their lines (a share of M:
    they are noisy).

    When ``eightpoint`` calls ``refineF`` (by any route: ``core.refine_switch``, the switch the
    grader uses too), the exact-match, rank and uint16 items are judged twice: on F as returned,
    and on F with refineF switched off (its minimisation skipped: it returns the closest rank-2
    matrix to the F it is given, unit norm), since refineF can hide a mistake made before it (a
    transposed F).
    """
    report = CheckReport("eightpoint")
    tv = scene or two_view()
    pair = tv.pair
    off = _switched_off(eightpoint)

    out = call(eightpoint, pair.pts1.copy(), pair.pts2.copy(), tv.M)
    if stop_if_not_implemented(report, out):
        return finish(report, verbose)
    if not run_failed(report, out, "exact matches of a generated scene"):
        F = read_or_report(report, jf.read_F, out.value, label="returns a 3x3 F (exact matches)")
        if F is not None:
            report.judged(jf.exact_fit(F, pair.pts1, pair.pts2, tv.M), "exact matches")
    out_off, refines = _off_value(call(off, pair.pts1.copy(), pair.pts2.copy(), tv.M))
    if refines and not run_failed(report, out_off, f"exact matches, {_OFF}"):
        F = read_or_report(report, jf.read_F, out_off.value, label=f"returns a 3x3 F (exact matches, {_OFF})")
        if F is not None:
            report.judged(jf.exact_fit(F, pair.pts1, pair.pts2, tv.M), f"exact matches, {_OFF}")

    # 20 noisy matches are enough (refineF's cost grows with them), seen by enlarged cameras as the
    # hidden check does (judging.fundamental.enlarged): every coordinate above 256 in both images,
    # so that any product of two overflows uint16 whatever the scene's size.
    k = slice(0, _N_NOISY)
    p1, M = jf.enlarged(tv.pts1_u16[k], tv.M)
    p2, _ = jf.enlarged(tv.pts2_u16[k], tv.M)
    runs = [("", eightpoint)] + ([(f", {_OFF}", off)] if refines else [])
    for suffix, fn in runs:
        out_f = call(fn, p1.astype(float), p2.astype(float), M)
        out_u = call(fn, p1.copy(), p2.copy(), M)
        if suffix:
            out_f, out_u = _off_value(out_f)[0], _off_value(out_u)[0]
        if run_failed(report, out_f, f"noisy matches (float{suffix})"):
            continue
        Ff = read_or_report(report, jf.read_F, out_f.value, label=f"returns a 3x3 F (noisy matches{suffix})")
        if Ff is None:
            continue
        report.judged(jf.rank_two(Ff, M), f"noisy matches{suffix}")
        if out_u.ok:
            Fu = read_or_report(report, jf.read_F, out_u.value, label=f"returns a 3x3 F (uint16 points{suffix})")
            if Fu is not None:
                report.judged(jf.uint16_same(Fu, Ff), suffix.lstrip(", "))
        else:
            report.add(f"runs on uint16 points (the data files' type{suffix})", False, out_u.message,
                       mistakes=[mistake("uint16_wraparound", "it fails on uint16 input only")])
    if refines:
        report.notes.append("your eightpoint calls refineF, so it was also run with refineF switched off (its "
                            "minimisation skipped: it returned the closest rank-2 matrix to the F it was given, "
                            "unit norm): refineF can hide a mistake made before it")

    data, note = default_temple(root) if scene is None else (None, "")
    if scene is None and data is None:
        report.notes.append(note)
    elif data is not None:
        out_d = call(eightpoint, data.pts1.copy(), data.pts2.copy(), data.M)
        if not run_failed(report, out_d, "the default data"):
            Fd = read_or_report(report, jf.read_F, out_d.value, label="returns a 3x3 F (default data)")
            if Fd is not None:
                # No ground truth: the given (noisy) matches are judged, as the handout uses them.
                report.judged(jf.fit(Fd, data.pts1, data.pts2, _default_goal(data.M), data.M), "default data")
    return finish(report, verbose, eightpoint, root)
