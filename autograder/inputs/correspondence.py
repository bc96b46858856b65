"""Q4.1 and Q4.2: the matching problems (images, true F, points with known true matches) and the reference's shares.

The hidden matching problems come from temples of their own (``matching_scenes``), drawn from the
secret (and the draw's salt) at the config's sizes but at the official pair's pixel scale: hand-ins
set their search ranges and windows in pixels on the official pair, whose matches lie up to 26 px
along the line; at the smaller hidden scenes' own focal lengths the matches lie within a few
pixels of (x1, y1), where a matcher that never leaves a +-10 px box, or searches the line F^T x1,
finds them too.  Camera 2 is panned a little more than in the other scenes (``MATCH_TOE_DEG``), so
that F x1 and F^T x1 part at the matches.  Q4.1 judges, in each, the points whose match neither
slip can reach (solutions.matching_styles.scene_problem's ``slips``); Q4.2 judges matching temple
2's structure on points spread over every depth.  Each draw renders these two temples besides the
other questions' (about a second each at 320 x 240).

Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera; C = K M.  Nothing here
reaches a student.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from judging import correspondence as jc

from .scenes import FIXED_LABELS, Scenes, TempleCase
from .shared import M1

# The official pair's focal length (px): the matching temples' disparities are the official's in
# pixels (inside scenes.envelope's DISPARITY_Y), whatever the image size.
MATCH_FOCAL = 1520.0
# Camera 2's nominal pan (degrees) in the matching temples: image 2 shifts sideways by about
# MATCH_FOCAL * toe (2-6 px with the seeded factor), so F^T x1 passes 4-12 px from most matches,
# and the x disparities stay inside scenes.envelope's DISPARITY_X.
MATCH_TOE_DEG = 0.15
# templeCoords drawn in each matching temple: Q4.1 judges those whose match lies in a band of
# disparities (solutions.matching_styles.scene_problem's slips), a fifth to a half of them.
MATCH_COORDS = 600
# Draws of a matching temple before giving up on the envelope (2 of the 80 first draws of the
# sweep's 20 secrets, under two configurations, were outside).
MATCH_TRIES = 5


@dataclass(frozen=True, eq=False)
class CorrespondenceCase:
    """One scene's matching problem: images, the true F, points of image 1 and their true matches."""

    key: str
    label: str
    im1: np.ndarray
    im2: np.ndarray
    F: np.ndarray
    pts1: np.ndarray        # (P, 2)
    truth2: np.ndarray      # (P, 2)
    C1: np.ndarray
    C2: np.ndarray
    tol: float
    ref_share: float        # the weakest correct matcher style's share within tol (solutions.matching_styles)
    ref_share_3d: float     # the weakest style's share of 3D points on the structure
    truth3d: np.ndarray = None   # (P, 3) the true points of pts1 (camera-1 frame)
    tol3d: np.ndarray = None     # (P,) their 3D tolerance (solutions.matching_styles.surface_tolerance)
    shares: tuple = ()           # ((style, share, share 3D), ...) the goal was set from
    flat_share_3d: float = 0.0   # what a flat temple reaches on the structure (EasyProblem.flat_share_3d)


@dataclass(frozen=True, eq=False)
class Correspondence:
    cases: tuple[CorrespondenceCase, ...]   # Q4.1's, one per scene
    points_case: CorrespondenceCase        # Q4.2's: matching temple 2, its points over every depth


def _correspondence_case(key, label, scene, count, rng, slips: bool = True) -> CorrespondenceCase:
    """The scene's easy points and the goal several matcher styles set on them
    (solutions.matching_styles.scene_problem; ``slips``: Q4.1's points, False: Q4.2's)."""
    from solutions.matching_styles import scene_problem

    rows, easy = scene_problem(scene, count, rng, slips=slips)
    p1 = np.column_stack([np.ravel(scene.x1), np.ravel(scene.y1)]).astype(float)
    return CorrespondenceCase(key, label, scene.im1, scene.im2, scene.F_true, p1[rows], scene.x2_true[rows],
                              scene.K1 @ M1, scene.K2 @ scene.M2, jc.tolerance(scene.width), easy.ref_share,
                              easy.ref_share_3d, scene.X_coords[rows], easy.tol3d, easy.shares,
                              easy.flat_share_3d)


def matching_labels(config) -> list[str]:
    """The scenes of Q4.1, as feedback names them (known before the scenes are made: one test each)."""
    return [f"hidden scene {k}" for k in range(1, min(2, len(config.temples)) + 1)] + (
        ["the default data"] if config.use_default_data else [])


def matching_scenes(scenes: Scenes) -> tuple[TempleCase, ...]:
    """The hidden temples of Q4.1 and Q4.2 (see the module docstring): one per scene of the config
    (the first two), at its size and noise, seeded from ``scenes``' draw; a temple outside the
    homework's envelope (``scenes.envelope``: disparities past the official pair's, say) is drawn
    again from the next seed."""
    return tuple(TempleCase(tc.label, _matching_temple(scenes, k, spec))
                 for k, (tc, spec) in enumerate(zip(scenes.hidden[:2], scenes.config.temples), start=1))


def _matching_temple(scenes: Scenes, k: int, spec):
    from scenes import envelope
    from scenes.temple import make_temple_scene

    for attempt in range(MATCH_TRIES):
        name = f"matching-temple-{k}" + (f"-{attempt}" if attempt else "")
        scene = make_temple_scene(scenes.seed(name), width=spec.width, height=spec.height, noise_px=spec.noise_px,
                                  focal=MATCH_FOCAL, toe_deg=MATCH_TOE_DEG, n_coords=MATCH_COORDS)
        outside = envelope.outside_envelope(scene, noise_px=spec.noise_px)
        if not outside:
            return scene
    raise ValueError(f"matching temple {k}: none inside the envelope in {MATCH_TRIES} draws ({outside[0]})")


def prepare_correspondence(scenes: Scenes) -> Correspondence:
    """The matching problems of the hidden matching temples (``matching_scenes``) and of the default
    data when ``scenes`` holds it (a draw made without it takes the batch's, ``combine_correspondence``)."""
    rng = np.random.default_rng(scenes.seed("matching"))
    matching = matching_scenes(scenes)
    tcs = [*matching, *([scenes.default] if scenes.default else [])]
    cases = tuple(_correspondence_case(f"scene{k}", tc.label, tc.scene, scenes.config.match_points, rng)
                  for k, tc in enumerate(tcs))
    if scenes.default is not None or not scenes.config.use_default_data:
        _check_labels(cases, scenes.config)
    # Q4.2 judges the temple's structure on matching temple 2: its points spread over every depth
    # (not the slips' band of disparities, a band of depths), so the relief is told from a flat temple.
    tc = matching[1]
    return Correspondence(cases, _correspondence_case("points", tc.label, tc.scene, scenes.config.match_points, rng,
                                                      slips=False))


def combine_correspondence(drawn: Correspondence, batch: Correspondence, config) -> Correspondence:
    """A draw's hidden problems with the batch's problem of the default data (``FIXED_LABELS``)."""
    cases = tuple(c for c in drawn.cases if c.label not in FIXED_LABELS) + tuple(
        c for c in batch.cases if c.label in FIXED_LABELS)
    _check_labels(cases, config)
    return Correspondence(cases, drawn.points_case)


def _check_labels(cases, config) -> None:
    # The tests are parametrized by matching_labels before any scene exists: they must agree.
    if [c.label for c in cases] != matching_labels(config):
        raise RuntimeError(f"matching_labels: expected {[c.label for c in cases]}, got {matching_labels(config)}")
