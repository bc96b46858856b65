"""Q3.3: ``findM2(F, pts1, pts2, K1, K2) -> (M2, C2, w)``: the right camera of the four (judging.pose).

E fixes camera 2 up to the four candidates of ``camera2`` and the scale of t, so M2 is compared
with the right candidate by rotation angle and direction of t only.  Inputs: an exact scene with
K1 != K2 and its true F, hidden scenes with the F the reference estimates from their noisy
matches, and the twisted-pair case of the draw (matches near the epipoles on which a depth test
of camera 1 only picks the twisted pair; the camera only is judged there).  C2 must be K2 M2,
and w the points triangulated with it.

Another year's ``findM2(F, pts1, pts2, intrinsics, filename=...)`` (2022-2024: intrinsics a dict
{'K1', 'K2'}) or ``findM2(pts1, pts2, F, K1, K2)`` (Fall 2023) is recognised by its parameters
and called that way (``judging.conventions``, as the self-check calls it); the feedback says how.
"""

from __future__ import annotations

import numpy as np
import pytest

from autograder.inputs.cases import M1, SECONDS
from autograder.feedback.words import read_returned
from judging import pose as jp
from judging.conventions import findM2_call
from judging.verdict import Malformed


@pytest.fixture(scope="session")
def pose(hidden):
    """The prepared inputs (``autograder.inputs.pose.Pose``)."""
    return hidden.prepared["pose"]


def findM2_args(case, signature) -> tuple[tuple, tuple[str, ...]]:
    """(arguments, their names) of findM2 for ``case`` in the convention ``signature`` was written for."""
    call = findM2_call(signature, case.F, case.pts1, case.pts2, case.K1, case.K2)
    return call.args, call.names


@pytest.fixture(scope="session")
def findM2_verdicts(student, pose, signatures) -> list:
    """Per case: (right_camera verdict, outputs verdict), or the Malformed: one request, judged once."""
    from solutions import triangulate

    sig = signatures("findM2")
    calls = [findM2_args(c, sig) for c in pose.cases]
    outcomes = student.each("findM2", [a for a, _ in calls], seconds=SECONDS["findM2"])
    out = []
    for case, o, (args, names) in zip(pose.cases, outcomes, calls):
        try:
            M2, C2, w = read_returned("findM2", o, lambda v, n=len(case.pts1): jp.read_findM2(v, n), args, names=names)
        except Malformed as exc:
            out.append(exc)
            continue
        linear_err = np.inf
        if np.all(np.isfinite(M2)):
            with np.errstate(all="ignore"):
                linear_err = triangulate(case.K1 @ M1, case.pts1, case.K2 @ M2, case.pts2)[1]
        out.append((jp.right_camera(M2, case.right, case.X),
                    jp.outputs(M2, C2, w, case.K1, case.K2, case.pts1, case.pts2, linear_err)
                    if case.judge_outputs else None))
    return out


def _mistakes(verdicts) -> list:
    return [m for v in verdicts if not isinstance(v, Malformed) for part in v if part is not None
            for m in part.mistakes]


@pytest.mark.points(8, question="Q3.3", name="M2 is the camera that puts the points in front of both cameras")
def test_M2_is_the_right_camera(pose, findM2_verdicts, signatures, score):
    lines = [f"{c.label}: {v if isinstance(v, Malformed) else v[0].sentence}"
             for c, v in zip(pose.cases, findM2_verdicts)]
    how = findM2_call(signatures("findM2"), None, None, None, None, None).how
    if how:
        lines.insert(0, how)
    right = sum(not isinstance(v, Malformed) and v[0].passed for v in findM2_verdicts)
    score.grade(right / len(pose.cases), lines, _mistakes(findM2_verdicts))


@pytest.mark.points(2, question="Q3.3", name="C2 = K2 M2 and w are the points triangulated with it")
def test_C2_and_w_go_with_M2(pose, findM2_verdicts, score):
    judged = [(c, v) for c, v in zip(pose.cases, findM2_verdicts) if c.judge_outputs]
    lines = [f"{c.label}: {v[1].sentence}" for c, v in judged if not isinstance(v, Malformed)]
    if not lines:
        lines.append(next((str(v) for _, v in judged if isinstance(v, Malformed)), "no result to check"))
    right = sum(not isinstance(v, Malformed) and v[1].passed for _, v in judged)
    score.grade(right / len(judged), lines, _mistakes(v for _, v in judged))
