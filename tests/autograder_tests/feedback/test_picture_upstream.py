"""A picture that fails, or looks wrong, because of another question's function says which
function and which question; an array returned for a number is said as such, not "not finite".

On the public default data, in this process (the reference functions of solutions/ as the
student's good ones, each bug a small stand-in)."""

from __future__ import annotations

import numpy as np
import pytest

import solutions
from autograder.feedback import pictures as step
from autograder.hidden.plugin import LocalStudent
from starter.checks import pictures

pytestmark = pytest.mark.slow   # each draws a real picture (seconds)


def _raises(*args, **kwargs):
    raise ValueError("a student's bug")


def compute3D_pts(temple_pts1, intrinsics, F, im1, im2):
    """2022-24's signature, with a findM2 inside that picked a wrong camera: a smear."""
    return np.random.default_rng(0).normal(size=(len(np.asarray(temple_pts1)), 3))


def test_q42_falls_back_to_the_matcher_and_triangulate_and_names_them():
    functions = {"compute3D_pts": _raises, "epipolarCorrespondence": solutions.epipolarCorrespondence,
                 "triangulate": solutions.triangulate}
    p = pictures.draw("Q4.2", pictures.public_outputs("Q4.2", functions))
    assert "epipolarCorrespondence (Q4.1) and triangulate (Q3.2)" in p.alt
    assert p.measures["route"] == 2 and p.measures["share_near"] > 0.5


def test_a_failing_triangulate_behind_q42_is_named_with_its_question():
    record = step.picture_record(LocalStudent({"compute3D_pts": _raises, "triangulate": _raises,
                                               "epipolarCorrespondence": solutions.epipolarCorrespondence}), "Q4.2")
    assert record["error"].startswith(step.NOT_DRAWN + "compute3D_pts raised ValueError"), record
    assert "triangulate (Q3.2): triangulate raised ValueError" in record["error"], record


def test_a_smear_from_another_years_compute3D_pts_names_findM2():
    p = pictures.draw("Q4.2", pictures.public_outputs("Q4.2", {"compute3D_pts": compute3D_pts}))
    assert p.measures["route"] == 1 and p.measures["share_near"] < 0.5
    assert "findM2 (Q3.3)" in p.alt and "far from the temple" in p.alt


def test_an_array_for_o1_is_said_as_an_array():
    def bundleAdjustment(K1, M1, p1, K2, M2_init, p2, P_init):
        M2, w, o1, o2 = solutions.bundleAdjustment(K1, M1, p1, K2, M2_init, p2, P_init)
        return M2, w, np.full(4, o1), o2

    p = pictures.draw("Q5", pictures.public_outputs("Q5", {"bundleAdjustment": bundleAdjustment}))
    assert "o1 is an array of 4 numbers, not one number" in p.alt
    assert "o1 = not finite" not in p.alt and "o2 = " in p.alt
