"""Public check of Q3.1: ``essentialMatrix(F, K1, K2) -> E``."""

from __future__ import annotations

import numpy as np

from . import mistakes as mk
from ._common import as_array, fig, finish, run_failed, stop_if_not_implemented
from ._scenes import default_temple, two_view
from .report import CheckReport, call

__all__ = ["check_essentialMatrix"]

_RTOL = 1e-6


def _judge(report: CheckReport, out, F, K1, K2, E_true, where: str) -> None:
    if run_failed(report, out, where):
        return
    E, why = as_array(out.value, (3, 3), "E")
    if E is None or not np.all(np.isfinite(E)) or not np.any(E):
        report.add(f"returns a 3x3 E ({where})", False, why or "E: expected finite numbers, not all zero")
        return
    a, b = E / np.linalg.norm(E), E_true / np.linalg.norm(E_true)
    dev = float(min(np.abs(a - b).max(), np.abs(a + b).max()))
    report.add(f"E is the true essential matrix up to scale ({where})", dev <= _RTOL,
               f"largest difference {fig(dev)} (unit norm)", f"< {_RTOL:g}",
               mk.essential_mistakes(E, F, K1, K2, _RTOL) if dev > _RTOL else ())
    s = np.linalg.svd(E, compute_uv=False)
    gap, last = 1.0 - s[1] / s[0], s[2] / s[0]
    report.add(f"two equal singular values and a zero ({where})", gap <= _RTOL and last <= _RTOL,
               f"1 - s2/s1 = {fig(gap)}, s3/s1 = {fig(last)}", f"both < {_RTOL:g}")


def check_essentialMatrix(essentialMatrix, *, root=None, verbose: bool = True) -> CheckReport:
    """Run ``essentialMatrix`` on exact fundamental matrices of known poses.

    Parameters
    ----------
    essentialMatrix : the student's function (F (3, 3), K1 (3, 3), K2 (3, 3)) -> E (3, 3).
    root : data folder for the default data's intrinsics (default: data/ or $HW4_DATA).
    verbose : print the report.

    Checked: E equals [t]x R of the true pose up to scale and sign (with K1 != K2, so that the
    order of the intrinsics matters), and its singular values are (s, s, 0).  With the default
    data's intrinsics the same is checked for a known pose.
    """
    report = CheckReport("essentialMatrix")
    tv = two_view()
    out = call(essentialMatrix, tv.F.copy(), tv.K1.copy(), tv.K2.copy())
    if stop_if_not_implemented(report, out):
        return finish(report, verbose)
    _judge(report, out, tv.F, tv.K1, tv.K2, tv.E, "generated, K1 != K2")

    data, note = default_temple(root)
    if data is None:
        report.notes.append(note)
    else:
        F = np.linalg.inv(data.K2).T @ tv.E @ np.linalg.inv(data.K1)
        F /= np.linalg.norm(F)
        out = call(essentialMatrix, F.copy(), data.K1.copy(), data.K2.copy())
        _judge(report, out, F, data.K1, data.K2, tv.E, "default data's K1, K2")
    return finish(report, verbose)
