"""Hidden checks of Q4.1, Q4.2 (judged by ``autograder/tests/correspondence.py`` until ``judging.correspondence`` replaces it)."""

from __future__ import annotations

import pytest

from autograder.tests import correspondence


@pytest.mark.points(15, question="Q4.1")
def test_Q4_1(legacy_judged, score):
    """epipolarCorrespondence on the hidden scenes."""
    score.record(legacy_judged(correspondence)["Q4.1"])


@pytest.mark.points(5, question="Q4.2")
def test_Q4_2(legacy_judged, score):
    """compute3D_pts on the hidden scenes."""
    score.record(legacy_judged(correspondence)["Q4.2"])
