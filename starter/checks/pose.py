"""Public check of Q3.3: ``findM2(F, pts1, pts2, K1, K2) -> (M2, C2, w)``; every verdict is judging.pose's.

Another year's findM2 (``findM2(F, pts1, pts2, intrinsics, filename=...)``, ``findM2(pts1, pts2,
F, K1, K2)``) is called as its parameters ask, by the rules the grader uses (judging.conventions).
"""

from __future__ import annotations

from core.geometry import IDENTITY_POSE
from judging import pose as jp
from judging.conventions import findM2_call, signature_of_callable

from ._common import finish, read_or_report, run_failed, stop_if_not_implemented
from ._scenes import NO_DEFAULT_DATA, NoisyPair, triangulation_goal, two_view
from .report import CheckReport, call
from .twisted_pair import TwistedPairCase, public_case

__all__ = ["check_findM2"]


def _judge(report, value, K1, K2, pts1, pts2, right, where, X=None, outputs=True) -> None:
    """Items for one findM2 result; ``value`` is M2 or a tuple starting with it.

    X : (N, 3) the true points (right's scale), for naming a depth test of one camera only.
    outputs : judge C2 and w too (not on the twisted-pair case, whose linear triangulations are
        far from optimal by construction).
    """
    got = read_or_report(report, jp.read_findM2, value, len(pts1), label=f"returns M2 (3x4) first ({where})")
    if got is None:
        return
    M2, C2, w = got
    report.judged(jp.right_camera(M2, right, X), where)
    if outputs and (C2 is not None or w is not None):
        # No reference triangulation: the goal is the lowest error reachable from w itself.
        linear = triangulation_goal(K1 @ IDENTITY_POSE, pts1, K2 @ M2, pts2, w)
        report.judged(jp.outputs(M2, C2, w, K1, K2, pts1, pts2, linear), where)


def check_findM2(findM2, *, scene: NoisyPair | None = None, F=None, right=None, twisted: TwistedPairCase | None = None,
                 root=None, verbose: bool = True) -> CheckReport:
    """Run ``findM2`` with a known F and known pose, and on matches that need the depth in both cameras.

    Parameters
    ----------
    findM2 : the student's function (F (3, 3), pts1 (N, 2), pts2 (N, 2), K1, K2) -> M2 (3, 4),
        or a tuple starting with M2 (the reference returns (M2, C2, w)).
    scene : the pair to check on (default: the public generated pair, K1 != K2).
    F, right : with ``scene``: the F to give (default the pair's true F, exact matches) with the
        scene's noisy matches, and the right camera for it (default the true pose).
    twisted : the twisted-pair case (starter.checks.twisted_pair; default: the public seed's,
        read from starter/checks/twisted_pair.json, when ``scene`` is None, none otherwise): matches near the epipoles on which a depth test of
        camera 1 only picks the twisted pair by its smaller error; the camera only is judged.
    root : accepted like every check's; the default data are not used (they have no true pose).
    verbose : print the report.

    Checked (judging.pose): R is a rotation and M2 is the right camera of the four (R, and t up
    to a positive scale); C2 = K2 M2 and w reprojects within 5 % of the lowest error reachable
    with them (w polished point by point).  A twisted pair returned on the twisted-pair case is
    named as a depth test of one camera only.
    """
    report = CheckReport("findM2")
    signature = signature_of_callable(findM2)

    def run(F_, p1, p2, K1, K2):
        c = findM2_call(signature, F_.copy(), p1.copy(), p2.copy(), K1.copy(), K2.copy())
        return call(findM2, *c.args)

    how = findM2_call(signature, None, None, None, None, None).how
    if how:
        report.notes.append(how)
    tv = scene or two_view()
    pair = tv.pair
    out = run(pair.F, pair.pts1, pair.pts2, pair.K1, pair.K2)
    if stop_if_not_implemented(report, out):
        return finish(report, verbose)
    if not run_failed(report, out, "a generated scene"):
        _judge(report, out.value, pair.K1, pair.K2, pair.pts1, pair.pts2, pair.M2, "generated")
    if F is not None:
        p1, p2 = tv.pts1_u16.astype(float), tv.pts2_u16.astype(float)
        out = run(F, p1, p2, pair.K1, pair.K2)
        if not run_failed(report, out, "noisy matches"):
            _judge(report, out.value, pair.K1, pair.K2, p1, p2, pair.M2 if right is None else right, "noisy")

    if twisted is None and scene is None:
        twisted = public_case()
    if twisted is not None:
        tp = twisted.pair
        out = run(tp.F, twisted.pts1, twisted.pts2, tp.K1, tp.K2)
        if not run_failed(report, out, "matches near the epipoles"):
            _judge(report, out.value, tp.K1, tp.K2, twisted.pts1, twisted.pts2, tp.M2, "near the epipoles",
                   X=tp.X, outputs=False)

    if scene is None:
        report.notes.append(NO_DEFAULT_DATA)
    return finish(report, verbose, findM2, root)
