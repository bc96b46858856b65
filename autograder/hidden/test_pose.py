"""Q3.3: ``findM2(F, pts1, pts2, K1, K2) -> (M2, C2, w)``: the right camera of the four (judging.pose).

E fixes camera 2 up to the four candidates of ``camera2`` and the scale of t, so M2 is compared
with the right candidate by rotation angle and direction of t only.  Inputs: an exact scene with
K1 != K2 and its true F, and hidden scenes with the F the reference estimates from their noisy
matches.  C2 must be K2 M2, and w the points triangulated with it.
"""

from __future__ import annotations

import numpy as np
import pytest

from autograder.hidden.cases import M1, SECONDS
from autograder.hidden.feedback import value_of
from judging import pose as jp
from judging.verdict import Malformed


@pytest.fixture(scope="session")
def pose(hidden):
    """The prepared inputs (``autograder.hidden.cases.Pose``)."""
    return hidden.prepared["pose"]


@pytest.fixture(scope="session")
def findM2_verdicts(student, pose) -> list:
    """Per case: (right_camera verdict, outputs verdict), or the Malformed: one request, judged once."""
    from solutions import triangulate

    outcomes = student.each("findM2", [(c.F, c.pts1, c.pts2, c.K1, c.K2) for c in pose.cases],
                            seconds=SECONDS["findM2"])
    out = []
    for case, o in zip(pose.cases, outcomes):
        try:
            M2, C2, w = jp.read_findM2(value_of("findM2", o), len(case.pts1))
        except Malformed as exc:
            out.append(exc)
            continue
        linear_err = np.inf
        if np.all(np.isfinite(M2)):
            with np.errstate(all="ignore"):
                linear_err = triangulate(case.K1 @ M1, case.pts1, case.K2 @ M2, case.pts2)[1]
        out.append((jp.right_camera(M2, case.right),
                    jp.outputs(M2, C2, w, case.K1, case.K2, case.pts1, case.pts2, linear_err)))
    return out


def _mistakes(verdicts) -> list:
    return [m for v in verdicts if not isinstance(v, Malformed) for part in v for m in part.mistakes]


@pytest.mark.points(8, question="Q3.3", name="M2 is the camera that puts the points in front of both cameras")
def test_M2_is_the_right_camera(pose, findM2_verdicts, score):
    lines = [f"{c.label}: {v if isinstance(v, Malformed) else v[0].sentence}"
             for c, v in zip(pose.cases, findM2_verdicts)]
    right = sum(not isinstance(v, Malformed) and v[0].passed for v in findM2_verdicts)
    score.grade(right / len(pose.cases), lines, _mistakes(findM2_verdicts))


@pytest.mark.points(2, question="Q3.3", name="C2 = K2 M2 and w are the points triangulated with it")
def test_C2_and_w_go_with_M2(pose, findM2_verdicts, score):
    lines = [f"{c.label}: {v[1].sentence}" for c, v in zip(pose.cases, findM2_verdicts)
             if not isinstance(v, Malformed)]
    if not lines:
        lines.append(next((str(v) for v in findM2_verdicts if isinstance(v, Malformed)), "no result to check"))
    right = sum(not isinstance(v, Malformed) and v[1].passed for v in findM2_verdicts)
    score.grade(right / len(pose.cases), lines, _mistakes(findM2_verdicts))
