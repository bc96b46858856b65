"""Hidden checks of Q5 (judged by ``autograder/tests/bundle.py`` until ``judging.bundle`` replaces it)."""

from __future__ import annotations

import pytest

from autograder.tests import bundle


@pytest.mark.points(20, question="Q5")
def test_Q5(legacy_judged, score):
    """rodriguesResidual and bundleAdjustment on the hidden scenes."""
    score.record(legacy_judged(bundle)["Q5"])
