"""Hidden checks of Q2 (judged by ``autograder/tests/fundamental.py`` until ``judging.fundamental`` replaces it)."""

from __future__ import annotations

import pytest

from autograder.tests import fundamental


@pytest.mark.points(10, question="Q2")
def test_Q2(legacy_judged, score):
    """eightpoint on the hidden scenes."""
    score.record(legacy_judged(fundamental)["Q2"])
