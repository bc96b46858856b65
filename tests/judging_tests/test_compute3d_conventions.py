"""Q4.2's conventions and its feedback when nothing counts (issue: "the verdicts real hand-ins
still get wrong"), graded by the real hidden tests in process (``run_here`` on a ``LocalStudent``)
under one of the sweep's secrets:

- compute3D_pts returning its points homogeneous (N x 4) is graded through compute3D_pts, at full
  marks, with no word of a wrong shape;
- 2022-2024's compute3D_pts(temple_pts1, intrinsics, F, im1, im2) indexing temple_pts1['x1'] (the
  loaded templeCoords mapping) is called with the mapping and gets full marks;
- when compute3D_pts raises and the matcher raises on some points, the feedback names the function
  that raised, the exception and how many points it failed on (not only "no result"), and the
  question of each function it fell back to ("triangulate (Q3.2)").
"""

from __future__ import annotations

import numpy as np
import pytest
import breadth

import solutions
from autograder.inputs.config import quick_config

pytestmark = pytest.mark.slow

_NAMES = ("eightpoint", "essentialMatrix", "triangulate", "findM2", "epipolarCorrespondence", "compute3D_pts")


@pytest.fixture(scope="module")
def hidden():
    from autograder.inputs.build import build_hidden_inputs
    from autograder.inputs.keep import default_keep

    return build_hidden_inputs(quick_config(secret=breadth.secrets("sweep-secret")[0]), keep=default_keep())


def _q42(hidden, **changes):
    from sweep import grade

    functions = {f: getattr(solutions, f) for f in _NAMES}
    functions.update(changes)
    score, full, tests = grade(functions, hidden, ["correspondence"])["Q4.2"]
    return score, full, "\n".join(t.feedback for t in tests)


def test_homogeneous_points_are_the_points(hidden):
    def compute3D_pts(im1, im2, F, x1, y1, C1, C2):
        w, pts2 = solutions.compute3D_pts(im1, im2, F, x1, y1, C1, C2)
        return np.hstack([2 * w, 2 * np.ones((len(w), 1))]), pts2

    score, full, feedback = _q42(hidden, compute3D_pts=compute3D_pts)
    assert score == full, feedback
    assert "graded through your compute3D_pts" in feedback and "should have shape" not in feedback, feedback


def test_the_templecoords_mapping_is_given_to_another_years_compute3D_pts(hidden):
    def compute3D_pts(temple_pts1, intrinsics, F, im1, im2):
        x1, y1 = temple_pts1["x1"], temple_pts1["y1"]       # IndexError on an N x 2 array
        pts1 = np.hstack([x1, y1]).astype(float)
        pts2 = np.array([solutions.epipolarCorrespondence(im1, im2, F, a[0], b[0]) for a, b in zip(x1, y1)])
        return solutions.findM2(F, pts1, pts2, intrinsics["K1"], intrinsics["K2"])[2]

    score, full, feedback = _q42(hidden, compute3D_pts=compute3D_pts)
    assert score == full, feedback
    assert "a dict of x1, y1 as templeCoords.npz" in feedback, feedback


def test_the_fallback_names_the_function_that_raised(hidden):
    def compute3D_pts(im1, im2, F, x1, y1, C1, C2):
        raise KeyError("temple")

    def epipolarCorrespondence(im1, im2, F, x1, y1):
        if int(x1) % 2:
            raise ValueError("window out of the image")
        return solutions.epipolarCorrespondence(im1, im2, F, x1, y1)

    score, full, feedback = _q42(hidden, compute3D_pts=compute3D_pts, epipolarCorrespondence=epipolarCorrespondence)
    assert score < full, feedback
    # the functions of other questions it fell back to are named with their questions
    fell_back = "graded through your epipolarCorrespondence (Q4.1) and triangulate (Q3.2) (compute3D_pts: "
    assert fell_back in feedback, feedback
    assert "KeyError" in feedback, feedback
    assert "epipolarCorrespondence failed on " in feedback and "ValueError: window out of the image" in feedback, feedback
