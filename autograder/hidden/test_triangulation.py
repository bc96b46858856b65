"""Hidden checks of Q3.2 (judged by ``autograder/tests/triangulation.py`` until ``judging.triangulation`` replaces it)."""

from __future__ import annotations

import pytest

from autograder.tests import triangulation


@pytest.mark.points(10, question="Q3.2")
def test_Q3_2(legacy_judged, score):
    """triangulate on the hidden scenes."""
    score.record(legacy_judged(triangulation)["Q3.2"])
