"""Public check of Q3.2: ``triangulate(C1, pts1, C2, pts2) -> (w, err)``; every verdict is judging.triangulation's."""

from __future__ import annotations

from judging import triangulation as jt

from ._common import finish, read_or_report, run_failed, stop_if_not_implemented
from ._scenes import NO_DEFAULT_DATA, NoisyPair, triangulation_goal, two_view
from .report import CheckReport, call

__all__ = ["check_triangulate"]


def _noisy_items(report, out, C1, p1, C2, p2, M2, X, where) -> None:
    if run_failed(report, out, where):
        return
    pair = read_or_report(report, jt.read_w_err, out.value, len(p1), label=f"returns (w (N, 3), err) ({where})")
    if pair is None:
        return
    w, err = pair
    report.judged(jt.err_reported(err, w, C1, p1, C2, p2), where)
    # No reference triangulation here: the goal is the lowest error reachable from the true
    # points or from the student's own (judging.triangulation.optimal_error), which a linear
    # triangulation comes within a few per cent of.
    report.judged(jt.noisy_error(w, C1, p1, C2, p2, triangulation_goal(C1, p1, C2, p2, X, w), M2), where)


def check_triangulate(triangulate, *, scene: NoisyPair | None = None, root=None, verbose: bool = True) -> CheckReport:
    """Run ``triangulate`` with true cameras of a generated scene.

    Parameters
    ----------
    triangulate : the student's function (C1 (3, 4), pts1 (N, 2), C2 (3, 4), pts2 (N, 2)) ->
        (w (N, 3), err), err the total squared reprojection error in pixels^2.
    scene : the pair to check on (default: the public generated pair, K1 != K2).
    root : accepted like every check's; the default data are not used (they have no cameras).
    verbose : print the report.

    Checked (judging.triangulation): exact matches give the true points; err is the sum of
    squares of the residuals of the returned points; on noisy (uint16) matches the points
    reproject within 20 % of the lowest error reachable (computed by polishing the true points
    and yours, one by one).
    """
    report = CheckReport("triangulate")
    tv = scene or two_view()
    pair = tv.pair
    out = call(triangulate, pair.C1, pair.pts1.copy(), pair.C2, pair.pts2.copy())
    if stop_if_not_implemented(report, out):
        return finish(report, verbose)
    if not run_failed(report, out, "exact matches of a generated scene"):
        got = read_or_report(report, jt.read_w_err, out.value, len(pair.X), label="returns (w (N, 3), err) (exact)")
        if got is not None:
            w, err = got
            report.judged(jt.exact_points(w, pair.X, pair.M2), "exact matches")
            report.judged(jt.err_reported(err, w, pair.C1, pair.pts1, pair.C2, pair.pts2), "exact matches")

    p1, p2 = tv.pts1_u16.copy(), tv.pts2_u16.copy()
    out = call(triangulate, pair.C1, p1, pair.C2, p2)
    _noisy_items(report, out, pair.C1, p1.astype(float), pair.C2, p2.astype(float), pair.M2, pair.X,
                 "noisy uint16 matches")
    if scene is None:
        report.notes.append(NO_DEFAULT_DATA)
    return finish(report, verbose, triangulate, root)
