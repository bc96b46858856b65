"""Q2: the inputs of ``eightpoint`` and their goals.

- ``cases``: noisy matches (the hidden scenes, each again with camera 2 given other intrinsics so
  that the scene tells F from F^T, the last hidden scene enlarged, the default data, the official
  data), each with the true matches F is evaluated on and the goal of
  ``judging.fundamental.fit``: FIT_FACTOR times the larger of the reference's RMS distance (the
  handout's method with and without refineF) and the noise the scene was made with.
- ``exact``: noise-free matches (of every hidden scene, of the exact two-view scene whose cameras
  have different intrinsics, of the enlarged scene), where F is exact up to EXACT_TOL * M.
- ``uint16``: the enlarged scene's matches as uint16, every coordinate above 256 in both images,
  so that any product of two wraps around in uint16 arithmetic.

The Q2 tests call eightpoint on all of them as given and again with refineF switched off.
Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera; C = K M.  Nothing here
reaches a student.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.geometry import symmetric_epipolar_distances
from judging import fundamental as jf

from .scenes import Scenes
from .shared import reference_F

__all__ = ["Fundamental", "FundamentalCase", "prepare_fundamental"]


@dataclass(frozen=True, eq=False)
class FundamentalCase:
    """One eightpoint input and what F is judged on.

    pts1, pts2 : (N, 2) the matches eightpoint gets (float64, or uint16 for ``Fundamental.uint16``).
    M : the scale eightpoint gets (the larger side of the image).
    eval1, eval2 : (P, 2) the matches F is judged on (true ones when known), pixels.
    goal : pixels; the fit goal for noisy matches, EXACT_TOL * M for noise-free ones.
    noise : the noise (pixels) of pts1, pts2 about the exact projections (0 for noise-free
        matches), None when unknown (the official data).
    reference : the RMS distances (pixels) of eval1, eval2 to the reference's F, with and
        without refineF (empty for noise-free matches).
    """

    label: str
    pts1: np.ndarray
    pts2: np.ndarray
    M: float
    eval1: np.ndarray
    eval2: np.ndarray
    goal: float
    noise: float | None = None
    reference: tuple[float, ...] = ()


@dataclass(frozen=True, eq=False)
class Fundamental:
    cases: tuple[FundamentalCase, ...]     # noisy: hidden scenes, the enlarged one, the default and official data
    exact: tuple[FundamentalCase, ...]     # noise-free matches
    uint16: FundamentalCase                # the enlarged scene's matches as uint16; its float twin is in cases

    @property
    def calls(self) -> int:
        """How many times the Q2 tests call eightpoint: every input as given and with refineF off."""
        return 2 * (len(self.cases) + len(self.exact) + 1)

    def float_twin(self) -> FundamentalCase:
        """The case of ``cases`` with the same points as ``uint16``, as float64."""
        return next(c for c in self.cases if c.label == self.uint16.label.rsplit(",", 1)[0])


_ENLARGED = "enlarged"


def _rms(F, eval1, eval2) -> float:
    d = symmetric_epipolar_distances(F, eval1, eval2)
    return float(np.sqrt(np.mean(d ** 2)))


def _reference_rms(pts1, pts2, M, eval1, eval2, refined=None) -> tuple[float, float]:
    """RMS distances of the evaluation matches to the reference's F with and without refineF
    (``refined``: the first when already made)."""
    from solutions import eightpoint

    p1, p2 = np.asarray(pts1, float), np.asarray(pts2, float)
    if refined is None:
        refined = eightpoint(p1, p2, M)
    return (_rms(refined, eval1, eval2), _rms(eightpoint(p1, p2, M, refine=False), eval1, eval2))


def _noisy_case(label, pts1, pts2, M, eval1, eval2, noise, refined=None) -> FundamentalCase:
    ref = _reference_rms(pts1, pts2, M, eval1, eval2, refined)
    return FundamentalCase(label, np.asarray(pts1, float), np.asarray(pts2, float), float(M),
                           np.asarray(eval1, float), np.asarray(eval2, float), jf.fit_goal(ref, noise), noise, ref)


def _exact_case(label, pts1, pts2, M) -> FundamentalCase:
    p1, p2 = np.array(pts1, dtype=float), np.array(pts2, dtype=float)
    return FundamentalCase(label, p1, p2, float(M), p1.copy(), p2.copy(), jf.EXACT_TOL * float(M), 0.0)


def _temple_case(tc) -> FundamentalCase:
    if not tc.has_truth:
        # No ground truth: the given matches, as the handout uses them; no known noise.
        return _noisy_case(tc.label, tc.pts1, tc.pts2, tc.M, tc.pts1, tc.pts2, None, reference_F(tc))
    s = tc.scene
    keep = s.visible2
    e1, e2 = np.column_stack([s.x1, s.y1]).astype(float)[keep], s.x2_true[keep]
    return _noisy_case(tc.label, tc.pts1, tc.pts2, tc.M, e1, e2, jf.noise_of(s.pts1, s.pts2, s.pts1_true, s.pts2_true),
                       reference_F(tc))


def _enlarged_cases(tc) -> tuple[FundamentalCase, FundamentalCase, FundamentalCase]:
    """(noisy float, uint16, noise-free) cases of the temple case ``tc`` seen by enlarged cameras
    (judging.fundamental.enlarged): every coordinate above 256 in both images."""
    s = tc.scene
    label = f"{tc.label}, {_ENLARGED}"
    p1, M = jf.enlarged(np.asarray(s.pts1), s.M)
    p2, _ = jf.enlarged(np.asarray(s.pts2), s.M)
    keep = s.visible2
    e1, _ = jf.enlarged(np.column_stack([s.x1, s.y1]).astype(float)[keep], s.M)
    e2, _ = jf.enlarged(s.x2_true[keep], s.M)
    x1, _ = jf.enlarged(s.pts1_true, s.M)
    x2, _ = jf.enlarged(s.pts2_true, s.M)
    noisy = _noisy_case(label, p1, p2, M, e1, e2, jf.noise_of(p1, p2, x1, x2))
    u16 = FundamentalCase(f"{label}, as uint16", p1.astype(np.uint16), p2.astype(np.uint16), M, e1, e2, noisy.goal,
                          noisy.noise, noisy.reference)
    return noisy, u16, _exact_case(f"noise-free matches of {label}", x1, x2, M)


# Camera 2 of a hidden scene given other intrinsics (zoom fx, fy and principal point moved by dx,
# dy of the image's size), tried in turn.  The temple's cameras share K and turn little, so its F
# is nearly skew-symmetric: F and F^T put nearly the same lines through the matches (the
# transposed true F lies within 0.2 to 1.2 fit goals of them on 16 of 16 scenes of 256 x 192), and
# no fit there tells an F from a transposed one polished by refineF.  With K2 != K1 they differ.
# Zooming out keeps the matches inside the image.
_OTHER_K2 = ((0.85, 0.87, -0.03, 0.03), (0.87, 0.85, 0.03, -0.03), (0.85, 0.85, 0.03, 0.03),
             (0.85, 0.85, -0.03, -0.03), (0.9, 0.92, -0.03, 0.03), (0.92, 0.9, 0.03, -0.03))
TELLS_TRANSPOSE = 1.5   # the transposed true F's RMS distance, in fit goals, of a scene that tells F from F^T


def _pixel_map(K, fx: float, fy: float, dx: float, dy: float) -> np.ndarray:
    """A (3, 3): pixels of camera K -> pixels of the camera with focal lengths times fx, fy and
    principal point moved by (dx, dy) pixels (A = K' K^-1)."""
    K2 = np.array(K, float)
    K2[0, 0] *= fx
    K2[1, 1] *= fy
    K2[0, 2] += dx
    K2[1, 2] += dy
    return K2 @ np.linalg.inv(K)


def _mapped(A, pts) -> np.ndarray:
    q = np.column_stack([np.asarray(pts, float), np.ones(len(pts))]) @ A.T
    return q[:, :2] / q[:, 2:]


def _other_camera_case(tc) -> FundamentalCase:
    """The noisy matches of the hidden scene ``tc`` with camera 2 given other intrinsics
    (``_OTHER_K2``): the first that keeps every match and evaluation point inside the image and F33
    inside the envelope and puts the transposed true F at least TELLS_TRANSPOSE fit goals off;
    failing that, the one of those inside the image that puts it furthest (every draw has as many
    cases, so the session's budget is the batch's).  The goal is the reference's there.  The
    envelope's disparities bound what a matcher searches: eightpoint is given its matches, as for
    the enlarged scene."""
    from core.geometry import fundamental_from_pose
    from scenes import envelope
    from solutions import eightpoint

    s = tc.scene
    keep = s.visible2
    e1, e2 = np.column_stack([s.x1, s.y1]).astype(float)[keep], s.x2_true[keep]
    size = np.array([s.width, s.height], float)
    F_true = fundamental_from_pose(s.K1, s.K2, s.M2)
    noise = jf.noise_of(s.pts1, s.pts2, s.pts1_true, s.pts2_true)
    label = f"{tc.label}, camera 2 with other intrinsics"
    tried = []
    for fx, fy, dx, dy in _OTHER_K2:
        A = _pixel_map(s.K2, fx, fy, dx * s.width, dy * s.height)
        p2, x2, f2 = _mapped(A, s.pts2), _mapped(A, s.pts2_true), _mapped(A, e2)
        F = np.linalg.inv(A).T @ F_true
        inside = all(np.all((q >= 0) & (q <= size - 1)) for q in (p2, x2, f2))
        if not (inside and envelope.corner_ratio(F) >= envelope.MIN_F33):
            continue
        # The goal without refineF first (cheap, and the larger of the two on these scenes).
        plain = _rms(eightpoint(s.pts1.astype(float), p2, s.M, refine=False), e1, f2)
        tells = _rms(F.T, e1, f2) / jf.fit_goal(plain, noise)
        tried.append((tells, p2, f2, F))
        if tells < TELLS_TRANSPOSE:
            continue
        case = _noisy_case(label, s.pts1, p2, s.M, e1, f2, noise)
        if _rms(F.T, e1, f2) >= TELLS_TRANSPOSE * case.goal:
            return case
    if not tried:
        raise RuntimeError(f"{tc.label}: no camera 2 of _OTHER_K2 keeps the matches inside the image")
    _, p2, f2, _ = max(tried, key=lambda t: t[0])
    return _noisy_case(label, s.pts1, p2, s.M, e1, f2, noise)


def prepare_fundamental(scenes: Scenes) -> Fundamental:
    temple = scenes.temple_cases()
    cases = [_temple_case(tc) for tc in temple]
    big, u16, big_exact = _enlarged_cases(scenes.hidden[-1])
    cases.insert(len(scenes.hidden), big)   # after the hidden scenes: the fixed data come last
    # Scenes that tell F from F^T (_OTHER_K2), right after the hidden scenes they come from.
    cases[len(scenes.hidden):len(scenes.hidden)] = [_other_camera_case(tc) for tc in scenes.hidden]
    exact = [_exact_case(f"noise-free matches of {tc.label}", tc.scene.pts1_true, tc.scene.pts2_true, tc.M)
             for tc in scenes.hidden]
    tv = scenes.two_view
    exact.append(_exact_case("noise-free matches, cameras with different intrinsics", tv.pts1, tv.pts2,
                             scenes.hidden[-1].M))
    exact.append(big_exact)
    return Fundamental(tuple(cases), tuple(exact), u16)
