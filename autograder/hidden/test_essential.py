"""Hidden checks of Q3.1 (judged by ``autograder/tests/essential.py`` until ``judging.essential`` replaces it)."""

from __future__ import annotations

import pytest

from autograder.tests import essential


@pytest.mark.points(5, question="Q3.1")
def test_Q3_1(legacy_judged, score):
    """essentialMatrix on the hidden scenes."""
    score.record(legacy_judged(essential)["Q3.1"])
