"""Public check of Q3.1: ``essentialMatrix(F, K1, K2) -> E``; every verdict is judging.essential's."""

from __future__ import annotations

import numpy as np

from core.geometry import fundamental_from_pose
from judging import essential as je

from ._common import finish, read_or_report, run_failed, stop_if_not_implemented
from ._scenes import NoisyPair, temple_data_or_note, two_view
from .report import CheckReport, call

__all__ = ["check_essentialMatrix"]


def _judge(report: CheckReport, out, F, K1, K2, where: str, true_F: bool = True) -> None:
    if run_failed(report, out, where):
        return
    E = read_or_report(report, je.read_E, out.value, label=f"returns a 3x3 E ({where})")
    if E is None:
        return
    report.judged(je.essential(E, F, K1, K2), where)
    if true_F:
        report.judged(je.singular_values(E), where)


def check_essentialMatrix(essentialMatrix, *, scene: NoisyPair | None = None, inputs=None, root=None,
                          verbose: bool = True) -> CheckReport:
    """Run ``essentialMatrix`` on exact fundamental matrices of known poses.

    Parameters
    ----------
    essentialMatrix : the student's function (F (3, 3), K1 (3, 3), K2 (3, 3)) -> E (3, 3).
    scene : the pair to check on (default: the public generated pair, K1 != K2).
    inputs : further (F, K1, K2) triples (any rank-2 F) to check E on.
    root : data folder for the default data's intrinsics (default: data/ or $HW4_DATA).
    verbose : print the report.

    Checked (judging.essential): E is the essential matrix of F, K1 and K2 up to scale and sign
    (with K1 != K2, so that the order of the intrinsics matters), and for a true F its singular values are (s, s, 0).
    With the default data's intrinsics the same is checked for a known pose.
    """
    report = CheckReport("essentialMatrix")
    pair = (scene or two_view()).pair
    out = call(essentialMatrix, pair.F.copy(), pair.K1.copy(), pair.K2.copy())
    if stop_if_not_implemented(report, out):
        return finish(report, verbose)
    _judge(report, out, pair.F, pair.K1, pair.K2, "generated, K1 != K2")
    for k, (F, K1, K2) in enumerate(inputs or (), start=1):
        F, K1, K2 = (np.array(a, float) for a in (F, K1, K2))
        _judge(report, call(essentialMatrix, F.copy(), K1.copy(), K2.copy()), F, K1, K2, f"input {k}", False)

    data, note = temple_data_or_note(root) if scene is None else (None, "")
    if scene is None and data is None:
        report.notes.append(note)
    elif data is not None:
        F = fundamental_from_pose(data.K1, data.K2, pair.M2)
        out = call(essentialMatrix, F.copy(), data.K1.copy(), data.K2.copy())
        _judge(report, out, F, data.K1, data.K2, "default data's K1, K2")
    return finish(report, verbose)
