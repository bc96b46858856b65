"""Hidden checks of Q3.3 (judged by ``autograder/tests/pose.py`` until ``judging.pose`` replaces it)."""

from __future__ import annotations

import pytest

from autograder.tests import pose


@pytest.mark.points(10, question="Q3.3")
def test_Q3_3(legacy_judged, score):
    """findM2 on the hidden scenes."""
    score.record(legacy_judged(pose)["Q3.3"])
