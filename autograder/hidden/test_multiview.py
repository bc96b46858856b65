"""Hidden checks of Q6 (judged by ``autograder/tests/multiview.py`` until ``judging.multiview`` replaces it)."""

from __future__ import annotations

import pytest

from autograder.tests import multiview


@pytest.mark.points(15, question="Q6")
def test_Q6(legacy_judged, score):
    """MultiviewReconstruction and plot_3d_keypoint_video on the hidden scenes."""
    score.record(legacy_judged(multiview)["Q6"])
