"""The hidden inputs of every check, cut from the hidden scenes, with the reference's results on them.

One module per concept of ``judging/`` (``cases.fundamental`` ... ``cases.multiview``), each with
its ``prepare_<concept>(scenes)``; ``prepare_all`` runs them all (``autograder.hidden.inputs``
makes them; the tests of ``autograder/hidden/test_<concept>.py`` read them through the ``hidden``
fixture as ``hidden.prepared["<concept>"]``).  ``base`` holds what they share: M1 and the time
each call of a student function may take (``SECONDS``), summed by ``call_seconds`` into the
session's budget.

Nothing here reaches a student: the values stay in the grader (the cache folder is 0700).
Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera; C = K M.
"""

from __future__ import annotations

from ..scenes import Scenes
from .base import M1, SECONDS
from .bundle import prepare_bundle
from .correspondence import matching_labels, prepare_correspondence
from .essential import prepare_essential
from .fundamental import prepare_fundamental
from .multiview import prepare_multiview
from .pose import prepare_pose
from .triangulation import prepare_triangulation

__all__ = ["CONCEPTS", "M1", "SECONDS", "call_seconds", "matching_labels", "prepare_all"]


CONCEPTS = {
    "fundamental": prepare_fundamental, "essential": prepare_essential, "triangulation": prepare_triangulation,
    "pose": prepare_pose, "correspondence": prepare_correspondence, "bundle": prepare_bundle,
    "multiview": prepare_multiview,
}


def prepare_all(scenes: Scenes) -> dict:
    """Every concept's prepared inputs, by concept name."""
    return {name: prepare(scenes) for name, prepare in CONCEPTS.items()}


def call_seconds(prepared: dict, time_scale: float) -> float:
    """Seconds the tests may give student code in all, summed as they ask (for the session's budget)."""
    s = SECONDS
    f, e, t, p = prepared["fundamental"], prepared["essential"], prepared["triangulation"], prepared["pose"]
    c, b, m = prepared["correspondence"], prepared["bundle"], prepared["multiview"]
    matching = sum(s["epipolarCorrespondence"] * len(k.pts1) for k in c.cases)
    points = s["epipolarCorrespondence"] * len(c.points_case.pts1) + s["compute3D_pts.triangulate"]
    return time_scale * (
        s["eightpoint"] * (len(f.cases) + 3) + s["essentialMatrix"] * (len(e.inputs) + 1)
        + s["triangulate"] * len(t.all) + s["findM2"] * len(p.cases)
        + 2 * matching + 3 * points
        + s["rodriguesResidual"] * len(b.residual_inputs) + s["bundleAdjustment"] * len(b.problems)
        + s["MultiviewReconstruction"] * (len(m.sequence) + len(m.probes)) + s["plot_3d_keypoint_video"]
    ) + 30
