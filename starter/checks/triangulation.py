"""Public check of Q3.2: ``triangulate(C1, pts1, C2, pts2) -> (w, err)``; every verdict is judging.triangulation's."""

from __future__ import annotations

from judging import triangulation as jt

from ._common import finish, read_or_report, run_failed, stop_if_not_implemented
from ._scenes import NoisyPair, default_temple, linear_triangulation_error, opencv_reference, two_view
from .report import CheckReport, call

__all__ = ["check_triangulate"]


def _noisy_items(report, out, C1, p1, C2, p2, M2, linear_err, where) -> None:
    if run_failed(report, out, where):
        return
    pair = read_or_report(report, jt.read_w_err, out.value, len(p1), label=f"returns (w (N, 3), err) ({where})")
    if pair is None:
        return
    w, err = pair
    report.judged(jt.err_reported(err, w, C1, p1, C2, p2), where)
    if linear_err is None:
        report.notes.append(f"OpenCV (cv2) is not installed: the error on {where} is not compared")
    else:
        report.judged(jt.noisy_error(w, C1, p1, C2, p2, linear_err, M2), where)


def check_triangulate(triangulate, *, scene: NoisyPair | None = None, root=None, verbose: bool = True) -> CheckReport:
    """Run ``triangulate`` with true cameras of a generated scene, and on the default data.

    Parameters
    ----------
    triangulate : the student's function (C1 (3, 4), pts1 (N, 2), C2 (3, 4), pts2 (N, 2)) ->
        (w (N, 3), err), err the total squared reprojection error in pixels^2.
    scene : the pair to check on (default: the public generated pair, K1 != K2).
    root : data folder for the default data (default: data/ or $HW4_DATA).
    verbose : print the report.

    Checked (judging.triangulation): exact matches give the true points; err is the sum of
    squares of the residuals of the returned points; on noisy (uint16) matches and on the
    default data the points reproject as well as a linear triangulation's (OpenCV's).
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
    f1, f2 = p1.astype(float), p2.astype(float)
    _noisy_items(report, out, pair.C1, f1, pair.C2, f2, pair.M2,
                 linear_triangulation_error(pair.C1, f1, pair.C2, f2), "noisy uint16 matches")

    data, note = default_temple(root) if scene is None else (None, "")
    ref, note_cv = opencv_reference(data) if data is not None else (None, "")
    if scene is None and (data is None or ref is None):
        report.notes.append(note or note_cv)
    elif ref is not None:
        out = call(triangulate, ref.C1.copy(), data.pts1.copy(), ref.C2.copy(), data.pts2.copy())
        _noisy_items(report, out, ref.C1, data.pts1, ref.C2, data.pts2, ref.M2, ref.err, "default data")
    return finish(report, verbose)
