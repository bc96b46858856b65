"""The hidden inputs of every check, cut from the hidden scenes, with the reference's results on them.

One module per concept of ``judging/`` (``inputs.fundamental`` ... ``inputs.multiview``), each with
its ``prepare_<concept>(scenes)``; ``prepare_all`` runs them all (``autograder.inputs.build``
makes them; the tests of ``autograder/hidden/test_<concept>.py`` read them through the ``hidden``
fixture as ``hidden.prepared["<concept>"]``).  ``base`` holds what they share: M1 and the time
each call of a student function may take (``SECONDS``), summed by ``call_seconds`` into the
session's budget.

``draw_all`` makes one submission's draw: every concept prepared on the scenes of that draw
(hidden temples, cars; no default or official data), then what the batch made from the default
and the official data (``FIXED_LABELS``: the same for every draw) put back in its place, so that
a draw costs only what depends on the submission.

Nothing here reaches a student: the values stay in the grader (the cache folder is 0700).
Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera; C = K M.
"""

from __future__ import annotations

import dataclasses

from autograder.inputs.scenes import FIXED_LABELS, Scenes
from autograder.inputs.shared import M1, SECONDS
from autograder.inputs.bundle import prepare_bundle
from autograder.inputs.correspondence import combine_correspondence, matching_labels, prepare_correspondence
from autograder.inputs.essential import prepare_essential
from autograder.inputs.fundamental import prepare_fundamental
from autograder.inputs.multiview import prepare_multiview
from autograder.inputs.pose import prepare_pose
from autograder.inputs.triangulation import prepare_triangulation

__all__ = ["CONCEPTS", "M1", "SECONDS", "call_seconds", "draw_all", "matching_labels", "prepare_all", "with_fixed"]


CONCEPTS = {
    "fundamental": prepare_fundamental, "essential": prepare_essential, "triangulation": prepare_triangulation,
    "pose": prepare_pose, "correspondence": prepare_correspondence, "bundle": prepare_bundle,
    "multiview": prepare_multiview,
}


def prepare_all(scenes: Scenes) -> dict:
    """Every concept's prepared inputs, by concept name."""
    return {name: prepare(scenes) for name, prepare in CONCEPTS.items()}


def draw_all(scenes: Scenes, batch: dict) -> dict:
    """Every concept's prepared inputs for the draw ``scenes`` (made with ``fixed=False``), with the
    parts of ``batch`` (``prepare_all`` of the unsalted scenes) made from the default and official data."""
    if scenes.default is not None or scenes.official is not None:
        raise ValueError("scenes: expected a draw without the default and official data (make_scenes(fixed=False)), "
                         "got one with them")
    return with_fixed(prepare_all(scenes), batch, scenes.config)


def with_fixed(drawn: dict, batch: dict, config) -> dict:
    """``drawn`` (``prepare_all`` of a draw's scenes, made with ``fixed=False``) with what ``batch``
    made from the default and official data put back in its place, under ``config``."""
    fixed = {name: [c for c in _cases_of(name, batch[name]) if c.label in FIXED_LABELS] for name in drawn}
    f, t, p = drawn["fundamental"], drawn["triangulation"], drawn["pose"]
    # (Q2's noise-free and uint16 cases are made from the draw's own hidden scenes: inputs.fundamental.)
    return {
        **drawn,
        "fundamental": dataclasses.replace(f, cases=(*f.cases, *fixed["fundamental"])),
        "triangulation": dataclasses.replace(t, noisy=(*t.noisy, *fixed["triangulation"])),
        "pose": dataclasses.replace(p, cases=(*p.cases, *fixed["pose"])),
        "correspondence": combine_correspondence(drawn["correspondence"], batch["correspondence"], config),
    }


def _cases_of(name: str, prepared) -> tuple:
    # The per-scene cases of a concept (those with a scene label); concepts of the hidden scenes
    # and cars only (essential, bundle, multiview) have none from the fixed data.
    return {"fundamental": lambda x: x.cases, "triangulation": lambda x: x.noisy, "pose": lambda x: x.cases,
            "correspondence": lambda x: x.cases}.get(name, lambda x: ())(prepared)


def call_seconds(prepared: dict, time_scale: float) -> float:
    """Seconds the tests may give student code in all, summed as they ask (for the session's budget)."""
    s = SECONDS
    f, e, t, p = prepared["fundamental"], prepared["essential"], prepared["triangulation"], prepared["pose"]
    c, b, m = prepared["correspondence"], prepared["bundle"], prepared["multiview"]
    matching = sum(s["epipolarCorrespondence"] * len(k.pts1) for k in c.cases)
    points = s["epipolarCorrespondence"] * len(c.points_case.pts1) + s["compute3D_pts.triangulate"]
    return time_scale * (
        s["eightpoint"] * f.calls + s["essentialMatrix"] * (len(e.inputs) + 1)
        + s["triangulate"] * len(t.all) + s["findM2"] * len(p.cases)
        + 2 * matching + 3 * points
        + s["rodriguesResidual"] * len(b.residual_inputs) + s["bundleAdjustment"] * len(b.problems)
        + s["MultiviewReconstruction"] * (len(m.sequence) + len(m.probes)) + s["plot_3d_keypoint_video"]
    ) + 30
