"""Public check of Q3.2: ``triangulate(C1, pts1, C2, pts2) -> (w, err)``."""

from __future__ import annotations

import numpy as np

from . import mistakes as mk
from ._common import as_array, fig, finish, run_failed, stop_if_not_implemented, unpack
from ._scenes import default_temple, opencv_reference, project, two_view
from .report import CheckReport, call

__all__ = ["check_triangulate", "read_w_err"]

_EXACT_RTOL = 1e-6
_ERR_SLACK = 1.2


def read_w_err(report: CheckReport, value, n: int, where: str):
    """(w (n, 3), err float) from a triangulate-like result, or (None, None) after reporting why."""
    pair, why = unpack(value, 2, "triangulate")
    w = err = None
    if pair is not None:
        w, why = as_array(pair[0], (n, 3), "w")
        if w is not None:
            e = np.asarray(pair[1], dtype=float) if np.size(pair[1]) == 1 else None
            err = float(e.reshape(())) if e is not None else None
            if err is None:
                w, why = None, f"err: expected one number, got {np.shape(pair[1])}"
    if w is None:
        report.add(f"returns (w (N, 3), err) ({where})", False, why)
        return None, None
    return w, err


def _sum_of_squares_item(report, w, err, C1, p1, C2, p2, where):
    r1, r2 = p1 - project(C1, w), p2 - project(C2, w)
    m = mk.error_not_sum_of_squares(err, r1, r2)
    total = float(np.sum(r1 ** 2) + np.sum(r2 ** 2))
    report.add(f"err is the sum of squared reprojection errors ({where})", m is None,
               f"err = {fig(err, 6)}", f"{fig(total, 6)} from your w", [m])
    return m is None


def check_triangulate(triangulate, *, root=None, verbose: bool = True) -> CheckReport:
    """Run ``triangulate`` with true cameras of a generated scene, and on the default data.

    Parameters
    ----------
    triangulate : the student's function (C1 (3, 4), pts1 (N, 2), C2 (3, 4), pts2 (N, 2)) ->
        (w (N, 3), err), err the total squared reprojection error in pixels^2.
    root : data folder for the default data (default: data/ or $HW4_DATA).
    verbose : print the report.

    Checked: exact matches give the true points and err = 0; on noisy (uint16) matches err is
    the sum of squares of the residuals of the returned points, no larger than the truth's,
    and every point is in front of both cameras; on the default data, with cameras that OpenCV
    recovers, err is close to a linear triangulation's.
    """
    report = CheckReport("triangulate")
    tv = two_view()
    n = len(tv.X)
    out = call(triangulate, tv.C1.copy(), tv.pts1.copy(), tv.C2.copy(), tv.pts2.copy())
    if stop_if_not_implemented(report, out):
        return finish(report, verbose)
    if not run_failed(report, out, "exact matches of a generated scene"):
        w, err = read_w_err(report, out.value, n, "exact matches")
        if w is not None:
            scale = float(np.median(np.linalg.norm(tv.X, axis=1)))
            dev = float(np.nanmax(np.linalg.norm(w - tv.X, axis=1))) / scale if np.all(np.isfinite(w)) else np.inf
            report.add("exact matches give the true 3D points", dev <= _EXACT_RTOL,
                       f"largest error {fig(dev)} of the scene's size", f"< {_EXACT_RTOL:g}",
                       [mk.points_behind_cameras(w, tv.M1, tv.M2)] if dev > _EXACT_RTOL else ())
            report.add("err is 0 for exact matches", abs(err) <= 1e-6, f"err = {fig(err)}", "< 1e-6")

    p1, p2 = tv.pts1_u16.copy(), tv.pts2_u16.copy()
    out = call(triangulate, tv.C1.copy(), p1, tv.C2.copy(), p2)
    if not run_failed(report, out, "noisy uint16 matches"):
        w, err = read_w_err(report, out.value, n, "noisy matches")
        if w is not None:
            f1, f2 = tv.pts1_u16.astype(float), tv.pts2_u16.astype(float)
            _sum_of_squares_item(report, w, err, tv.C1, f1, tv.C2, f2, "noisy matches")
            err_true = float(np.sum((f1 - project(tv.C1, tv.X)) ** 2) + np.sum((f2 - project(tv.C2, tv.X)) ** 2))
            report.add("err no larger than the true points' error", 0 <= err <= _ERR_SLACK * err_true,
                       f"err = {fig(err)}", f"0 ... {fig(_ERR_SLACK * err_true)} ({_ERR_SLACK:g} x the truth's)")
            m = mk.points_behind_cameras(w, tv.M1, tv.M2, max_share=0.0)
            z = np.minimum(w @ tv.M1[2, :3] + tv.M1[2, 3], w @ tv.M2[2, :3] + tv.M2[2, 3])
            report.add("points in front of both cameras", m is None,
                       f"{int(np.sum(z > 0))} of {n}", "all", [m])

    data, note = default_temple(root)
    ref, note_cv = opencv_reference(data) if data is not None else (None, "")
    if data is None or ref is None:
        report.notes.append(note or note_cv)
    else:
        out = call(triangulate, ref.C1.copy(), data.pts1.copy(), ref.C2.copy(), data.pts2.copy())
        if not run_failed(report, out, "the default data"):
            w, err = read_w_err(report, out.value, len(data.pts1), "default data")
            if w is not None:
                _sum_of_squares_item(report, w, err, ref.C1, data.pts1, ref.C2, data.pts2, "default data")
                goal = _ERR_SLACK * ref.err + 1.0
                report.add("default data: err close to a linear triangulation's", 0 <= err <= goal,
                           f"err = {fig(err)}", f"<= {fig(goal)} (OpenCV's cameras: {fig(ref.err)})")
    return finish(report, verbose)
