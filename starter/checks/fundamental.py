"""Public check of Q2: ``eightpoint(pts1, pts2, M) -> F``."""

from __future__ import annotations

import numpy as np

from starter.epipolar import epipolar_distances

from . import mistakes as mk
from ._common import as_array, fig, finish, run_failed, stop_if_not_implemented
from ._scenes import default_temple, two_view
from .report import CheckReport, call

__all__ = ["check_eightpoint"]

_EXACT_TOL_PX = 0.01
_RANK_RTOL = 1e-6
_DEFAULT_MEAN_PX = 5.0
_N_NOISY = 20


def _as_F(report: CheckReport, value, where: str):
    F, why = as_array(value, (3, 3), "F")
    if F is not None and not (np.all(np.isfinite(F)) and np.any(F)):
        F, why = None, "F: expected finite numbers, not all zero"
    if F is None:
        report.add(f"returns a 3x3 F ({where})", False, why)
    return F


def check_eightpoint(eightpoint, *, root=None, verbose: bool = True) -> CheckReport:
    """Run ``eightpoint`` on generated matches with a known F, and on the default data.

    Parameters
    ----------
    eightpoint : the student's function (pts1 (N, 2), pts2 (N, 2), M) -> F (3, 3), pixels
        (x, y) = (column, row), x2^T F x1 = 0.
    root : data folder for the default data (default: data/ or $HW4_DATA).
    verbose : print the report.

    Checked: exact matches of a generated scene lie on the epipolar lines of F (so F equals the
    true F up to scale); F has rank 2 on noisy matches; uint16 points give the same F as float
    points; on the default data the matches lie near their lines (a few pixels: they are noisy).
    """
    report = CheckReport("eightpoint")
    tv = two_view()

    out = call(eightpoint, tv.pts1.copy(), tv.pts2.copy(), tv.M)
    if stop_if_not_implemented(report, out):
        return finish(report, verbose)
    if not run_failed(report, out, "exact matches of a generated scene"):
        F = _as_F(report, out.value, "exact matches")
        if F is not None:
            d = float(np.max(epipolar_distances(F, tv.pts1, tv.pts2)))
            report.add("exact matches lie on their epipolar lines", d <= _EXACT_TOL_PX,
                       f"max distance {fig(d)} px", f"< {_EXACT_TOL_PX} px",
                       mk.fundamental_mistakes(F, tv.pts1, tv.pts2, tv.M, _EXACT_TOL_PX) if d > _EXACT_TOL_PX else ())

    # 20 noisy matches are enough (and still overflow uint16): refineF's cost grows with them.
    k = slice(0, _N_NOISY)
    out_u = call(eightpoint, tv.pts1_u16[k].copy(), tv.pts2_u16[k].copy(), tv.M)
    out_f = call(eightpoint, tv.pts1_u16[k].astype(float), tv.pts2_u16[k].astype(float), tv.M)
    if not run_failed(report, out_f, "noisy matches (float)"):
        Ff = _as_F(report, out_f.value, "noisy matches")
        if Ff is not None:
            S = np.diag([tv.M, tv.M, 1.0])
            s = np.linalg.svd(S @ Ff @ S, compute_uv=False)
            ratio = s[2] / s[1] if s[1] > 0 else np.inf
            report.add("rank 2 (noisy matches)", ratio <= _RANK_RTOL, f"s3/s2 = {fig(ratio)}",
                       f"< {_RANK_RTOL:g}", [mk.rank2_not_enforced(Ff, tv.M, _RANK_RTOL)])
            if out_u.ok:
                Fu, why = as_array(out_u.value, (3, 3), "F")
                same = Fu is not None and mk.same_up_to_scale(Fu, Ff, 1e-6)
                report.add("uint16 points give the same F as float points", same,
                           "same F" if same else (why or "different F"), "",
                           [] if same else [mk.uint16_wraparound(Fu if Fu is not None else np.zeros((3, 3)), Ff)])
            else:
                report.add("runs on uint16 points (the data files' type)", False, out_u.message,
                           mistakes=[mk.mistake("uint16_wraparound", "it fails on uint16 input only")])

    data, note = default_temple(root)
    if data is None:
        report.notes.append(note)
    else:
        out_d = call(eightpoint, data.pts1.copy(), data.pts2.copy(), data.M)
        if not run_failed(report, out_d, "the default data"):
            Fd = _as_F(report, out_d.value, "default data")
            if Fd is not None:
                # No comparison with F^T here: with near-vertical epipolar lines and noisy matches
                # F^T can fit almost as well (on a small pair, better than an unrefined right F).
                dist = float(np.mean(epipolar_distances(Fd, data.pts1, data.pts2)))
                ok = dist <= _DEFAULT_MEAN_PX
                found = [] if ok else mk.fundamental_mistakes(Fd, data.pts1, data.pts2, data.M, _DEFAULT_MEAN_PX,
                                                              statistic="mean")
                report.add("default data: matches near their epipolar lines", ok, f"mean {fig(dist)} px",
                           f"< {_DEFAULT_MEAN_PX:g} px", found)
    return finish(report, verbose)
