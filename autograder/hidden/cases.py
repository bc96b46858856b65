"""The hidden inputs of every check, cut from the hidden scenes, with the reference's results on them.

One ``prepare_<concept>(scenes)`` per concept of ``judging/`` (made once per batch by
``autograder.hidden.inputs``; the tests of ``autograder/hidden/test_<concept>.py`` read them
through the ``hidden`` fixture as ``hidden.prepared["<concept>"]``).  The time each call of a
student function may take is here too (``SECONDS``), so that the session's budget is the sum of
what the tests will ask for (``call_seconds``).

Nothing here reaches a student: the values stay in the grader (the cache folder is 0700).
Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera; C = K M.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from core.geometry import project, symmetric_epipolar_distances
from judging import correspondence as jc
from judging import fundamental as jf
from judging import multiview as jm
from judging.bundle import total_error
from judging.pose import pose_gap
from starter.checks.bundle import BAProblem

from .scenes import Scenes

__all__ = ["CONCEPTS", "M1", "SECONDS", "call_seconds", "matching_labels", "prepare_all"]

M1 = np.hstack([np.eye(3), np.zeros((3, 1))])

# Seconds a student function may take per input (times the config's time_scale).
SECONDS = {
    "eightpoint": 5.0, "essentialMatrix": 2.0, "triangulate": 3.0, "findM2": 5.0,
    "epipolarCorrespondence": 0.5, "compute3D_pts.triangulate": 5.0,
    "rodriguesResidual": 2.0, "bundleAdjustment": 60.0, "MultiviewReconstruction": 5.0,
    "plot_3d_keypoint_video": 30.0,
}


# ------------------------------------------------------------------------------- Q2 fundamental


@dataclass(frozen=True, eq=False)
class FundamentalCase:
    """One eightpoint input: pts1, pts2 (N, 2), M; eval1, eval2 (P, 2) true matches; goal in px."""

    label: str
    pts1: np.ndarray
    pts2: np.ndarray
    M: float
    eval1: np.ndarray
    eval2: np.ndarray
    goal: float


@dataclass(frozen=True, eq=False)
class Fundamental:
    cases: tuple[FundamentalCase, ...]     # hidden scenes, the default data, the official data
    exact: FundamentalCase                 # noise-free matches
    uint16: FundamentalCase                # a scene's matches as the data files' uint16


_EXACT_TOL_PX = 0.05


def _hartley(pts1, pts2):
    """F by the reference eight-point with Hartley's normalisation instead of 1/M (a valid variant)."""
    from solutions import eightpoint
    from starter.ransac import eightpoint_hartley

    F = eightpoint_hartley(lambda a, b, M: eightpoint(a, b, M, refine=False), pts1, pts2)
    return F / np.linalg.norm(F)


def _rms(F, eval1, eval2) -> float:
    d = symmetric_epipolar_distances(F, eval1, eval2)
    return float(np.sqrt(np.mean(d ** 2)))


def _evaluation_matches(case) -> tuple[np.ndarray, np.ndarray]:
    if not case.has_truth:
        return case.pts1, case.pts2  # no ground truth: the given matches, as the handout uses them
    s = case.scene
    keep = s.visible2
    return np.column_stack([s.x1, s.y1]).astype(float)[keep], s.x2_true[keep]


def _fundamental_case(label, pts1, pts2, M, eval1, eval2) -> FundamentalCase:
    from solutions import eightpoint

    p1, p2 = np.asarray(pts1, float), np.asarray(pts2, float)
    variants = [eightpoint(p1, p2, M), eightpoint(p1, p2, M, refine=False), _hartley(p1, p2)]
    worst = max(_rms(F, eval1, eval2) for F in variants)
    return FundamentalCase(label, pts1, pts2, float(M), eval1, eval2, jf.fit_goal([worst]))


def prepare_fundamental(scenes: Scenes) -> Fundamental:
    cases = []
    for tc in scenes.temple_cases():
        e1, e2 = _evaluation_matches(tc)
        cases.append(_fundamental_case(tc.label, tc.pts1, tc.pts2, tc.M, e1, e2))
    base = scenes.default or scenes.hidden[-1]
    s = base.scene
    exact = FundamentalCase("noise-free matches", s.pts1_true.copy(), s.pts2_true.copy(), float(s.M),
                            s.pts1_true, s.pts2_true, _EXACT_TOL_PX)
    e1, e2 = _evaluation_matches(base)
    ref = next(c for c in cases if c.label == base.label)
    uint16 = FundamentalCase(f"{base.label}, as uint16", s.pts1.astype(np.uint16), s.pts2.astype(np.uint16),
                             float(s.M), e1, e2, ref.goal)
    return Fundamental(tuple(cases), exact, uint16)


# ------------------------------------------------------------------------------- Q3.1 essential


@dataclass(frozen=True, eq=False)
class Essential:
    inputs: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]   # (F, K1, K2): random rank-2 F's
    true_F: tuple[np.ndarray, np.ndarray, np.ndarray]               # (F, K1, K2) of an exact scene


def _random_K(rng) -> np.ndarray:
    f = rng.uniform(300, 2000)
    return np.array([[f, rng.uniform(-2, 2), rng.uniform(150, 500)],
                     [0.0, f * rng.uniform(0.95, 1.05), rng.uniform(100, 400)],
                     [0.0, 0.0, 1.0]])


def _random_F(rng) -> np.ndarray:
    U = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    V = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    F = U @ np.diag([1.0, rng.uniform(0.2, 0.9), 0.0]) @ V.T
    return F / np.linalg.norm(F)


def prepare_essential(scenes: Scenes) -> Essential:
    """Three random rank-2 F's with random K1 != K2 (swapped, missing or inverted K's all show) and
    the true F of an exact two-view scene."""
    rng = np.random.default_rng(scenes.config.seed("essential") % 2**63)
    inputs = tuple((_random_F(rng), _random_K(rng), _random_K(rng)) for _ in range(3))
    tv = scenes.two_view
    return Essential(inputs, (tv.F, tv.K1, tv.K2))


# ------------------------------------------------------------------------------- Q3.2 triangulation


@dataclass(frozen=True, eq=False)
class TriangulationCase:
    label: str
    C1: np.ndarray
    pts1: np.ndarray
    C2: np.ndarray
    pts2: np.ndarray
    M2: np.ndarray
    linear_err: float             # the reference's (linear) triangulation error (noisy cases)
    X: np.ndarray | None = None   # true points (exact case)


@dataclass(frozen=True, eq=False)
class Triangulation:
    exact: TriangulationCase
    noisy: tuple[TriangulationCase, ...]

    @property
    def all(self) -> tuple[TriangulationCase, ...]:
        return (self.exact, *self.noisy)


def prepare_triangulation(scenes: Scenes) -> Triangulation:
    from solutions import eightpoint, findM2, triangulate

    tv = scenes.two_view
    exact = TriangulationCase("noise-free matches", tv.C1, tv.pts1, tv.C2, tv.pts2, tv.M2, 0.0, tv.X)
    noisy = []
    for tc in [*scenes.hidden, *([scenes.official] if scenes.official else [])]:
        C1 = tc.K1 @ M1
        if tc.has_truth:
            M2 = tc.scene.M2
        else:
            M2 = findM2(eightpoint(tc.pts1, tc.pts2, tc.M), tc.pts1, tc.pts2, tc.K1, tc.K2)[0]
        C2 = tc.K2 @ M2
        _, err = triangulate(C1, tc.pts1, C2, tc.pts2)
        noisy.append(TriangulationCase(tc.label, C1, tc.pts1, C2, tc.pts2, M2, err))
    return Triangulation(exact, tuple(noisy))


# ------------------------------------------------------------------------------- Q3.3 pose


@dataclass(frozen=True, eq=False)
class PoseCase:
    label: str
    F: np.ndarray
    pts1: np.ndarray
    pts2: np.ndarray
    K1: np.ndarray
    K2: np.ndarray
    right: np.ndarray    # (3, 4) the right candidate


@dataclass(frozen=True, eq=False)
class Pose:
    cases: tuple[PoseCase, ...]


def _nearest(candidates: np.ndarray, truth: np.ndarray) -> np.ndarray:
    gaps = [max(pose_gap(candidates[:, :, i], truth)) for i in range(candidates.shape[2])]
    return candidates[:, :, int(np.argmin(gaps))]


def prepare_pose(scenes: Scenes) -> Pose:
    """An exact scene (K1 != K2) with its true F, and hidden scenes with the reference's F of their
    noisy matches; the right candidate is the one nearest the true pose (the reference's choice on
    the official data, which has no truth)."""
    from solutions import eightpoint, essentialMatrix, findM2
    from starter import camera2

    tv = scenes.two_view
    cases = [PoseCase("noise-free matches", tv.F, tv.pts1, tv.pts2, tv.K1, tv.K2, tv.M2)]
    for tc in [scenes.hidden[0], *([scenes.official] if scenes.official else [])]:
        F = eightpoint(tc.pts1, tc.pts2, tc.M)
        if tc.has_truth:
            right = _nearest(camera2(essentialMatrix(F, tc.K1, tc.K2)), tc.scene.M2)
        else:
            right = findM2(F, tc.pts1, tc.pts2, tc.K1, tc.K2)[0]
        cases.append(PoseCase(tc.label, F, tc.pts1, tc.pts2, tc.K1, tc.K2, right))
    return Pose(tuple(cases))


# ------------------------------------------------------------------------------- Q4 correspondence


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
    ref_share: float        # the reference matcher's share within tol
    ref_share_3d: float     # the reference compute3D_pts's share of right 3D points


@dataclass(frozen=True, eq=False)
class Correspondence:
    cases: tuple[CorrespondenceCase, ...]
    points_case: CorrespondenceCase        # the scene of Q4.2


def _correspondence_case(key, label, scene, count, rng) -> CorrespondenceCase:
    """Points whose true match is known (unoccluded, and far enough from the point itself that
    returning (x1, y1) or a nearby pixel cannot pass), with the reference's shares on them."""
    from solutions import compute3D_pts, epipolarCorrespondence

    W, H = scene.width, scene.height
    tol = jc.tolerance(W)
    p1 = np.column_stack([scene.x1, scene.y1]).astype(float)
    disparity = np.linalg.norm(scene.x2_true - p1, axis=1)
    margin = 8
    inside = np.all((p1 >= margin) & (p1 <= [W - 1 - margin, H - 1 - margin]), axis=1)
    eligible = np.flatnonzero(scene.visible2 & inside & (disparity > 2 * tol))
    if len(eligible) < 8:  # a degenerate hidden scene would make the check meaningless
        eligible = np.flatnonzero(scene.visible2 & inside)
    idx = np.sort(rng.choice(eligible, size=min(count, len(eligible)), replace=False))
    pts1, truth2 = p1[idx], scene.x2_true[idx]
    F = scene.F_true
    ref = np.array([epipolarCorrespondence(scene.im1, scene.im2, F, x, y) for x, y in pts1])
    C1, C2 = scene.K1 @ M1, scene.K2 @ scene.M2
    case = CorrespondenceCase(key, label, scene.im1, scene.im2, F, pts1, truth2, C1, C2, tol,
                              float(np.mean(jc.right_2d(ref, truth2, tol))), 0.0)
    w_ref, _ = compute3D_pts(scene.im1, scene.im2, F, pts1[:, :1], pts1[:, 1:], C1, C2)
    return dataclasses.replace(case, ref_share_3d=float(np.mean(jc.right_3d(w_ref, C1, C2, pts1, truth2, tol))))


def matching_labels(config) -> list[str]:
    """The scenes of Q4.1, as feedback names them (known before the scenes are made: one test each)."""
    return [f"hidden scene {k}" for k in range(1, min(2, len(config.temples)) + 1)] + (
        ["the default data"] if config.use_default_data else [])


def prepare_correspondence(scenes: Scenes) -> Correspondence:
    rng = np.random.default_rng(scenes.config.seed("matching"))
    tcs = [*scenes.hidden[:2], *([scenes.default] if scenes.default else [])]
    cases = tuple(_correspondence_case(f"scene{k}", tc.label, tc.scene, scenes.config.match_points, rng)
                  for k, tc in enumerate(tcs))
    if [c.label for c in cases] != matching_labels(scenes.config):
        raise RuntimeError(f"matching_labels: expected {[c.label for c in cases]}, got {matching_labels(scenes.config)}")
    return Correspondence(cases, cases[1])


# ------------------------------------------------------------------------------- Q5 bundle adjustment


@dataclass(frozen=True, eq=False)
class Bundle:
    problems: tuple[BAProblem, ...]        # the public check's problem type; optimum: the lowest error found
    residual_inputs: tuple[tuple, ...]     # (K1, M1, p1, K2, p2, x) of rodriguesResidual


_SWING_DEG = 20.0
_NOISE_PX = 0.5


def _rotation(axis, degrees) -> np.ndarray:
    from starter import rodrigues

    axis = np.asarray(axis, float)
    return rodrigues(np.radians(degrees) * axis / np.linalg.norm(axis))


def _gauge_fixed_optimum(K1, K2, p1, p2, M2_init, w_init) -> float:
    # t moves on the sphere of its initial length through two tangent coordinates, so the
    # scale cannot collapse; Levenberg-Marquardt from the start converges in a few dozen steps.
    import scipy.optimize

    from starter import invRodrigues, rodrigues

    n = len(p1)
    t0 = M2_init[:, 3]
    radius = np.linalg.norm(t0)
    direction = t0 / radius
    tangent = np.linalg.svd(direction[None, :])[2][1:].T

    def residuals(z):
        d = direction + tangent @ z[-2:]
        M2 = np.hstack([rodrigues(z[3 * n:3 * n + 3]), (radius * d / np.linalg.norm(d))[:, None]])
        w = z[:3 * n].reshape(n, 3)
        return np.concatenate([(p1 - project(K1 @ M1, w)).ravel(), (p2 - project(K2 @ M2, w)).ravel()])

    z0 = np.concatenate([w_init.ravel(), invRodrigues(M2_init[:, :3]), np.zeros(2)])
    fit = scipy.optimize.least_squares(residuals, z0, method="lm")
    return float(np.sum(fit.fun ** 2))


def _bundle_problem(label, scene, count, rng) -> BAProblem:
    """The points of a hidden scene seen from a second camera swung further round (well
    conditioned), 0.5 px of noise; the start 1-2 degrees and 5 degrees off, |t| = 1 as findM2 gives."""
    from solutions import bundleAdjustment, triangulate

    idx = np.sort(rng.choice(len(scene.X), size=min(count, len(scene.X)), replace=False))
    X = scene.X[idx]
    centre = X.mean(axis=0)
    axis = np.array([rng.normal(), rng.normal(), 0.2 * rng.normal()])
    R = _rotation(axis, _SWING_DEG)
    t = centre - R @ centre                     # turns the world about the points' centre
    K1, K2 = scene.K1, scene.K2
    p1 = project(K1 @ M1, X) + _NOISE_PX * rng.normal(size=(len(X), 2))
    p2 = project(K2 @ np.hstack([R, t[:, None]]), X) + _NOISE_PX * rng.normal(size=(len(X), 2))
    R0 = _rotation(rng.normal(size=3), 2.0) @ R
    t0 = _rotation(rng.normal(size=3), 5.0) @ (t / np.linalg.norm(t))
    M2_init = np.hstack([R0, t0[:, None]])
    w_init, _ = triangulate(K1 @ M1, p1, K2 @ M2_init, p2)
    optimum = _gauge_fixed_optimum(K1, K2, p1, p2, M2_init, w_init)
    M2_ref, w_ref, _, _ = bundleAdjustment(K1, M1, p1, K2, M2_init, p2, w_init)
    if np.linalg.norm(M2_ref[:, 3]) >= 0.5 * np.linalg.norm(M2_init[:, 3]):  # a collapsed optimum is no goal
        optimum = min(optimum, total_error(K1, K2, p1, p2, M2_ref, w_ref))
    return BAProblem(label, K1, K2, p1, p2, M2_init, w_init, optimum)


def _x_of(problem: BAProblem) -> np.ndarray:
    from starter import invRodrigues

    return np.concatenate([problem.w_init.ravel(), invRodrigues(problem.M2_init[:, :3]), problem.M2_init[:, 3]])


def prepare_bundle(scenes: Scenes) -> Bundle:
    rng = np.random.default_rng(scenes.config.seed("bundle"))
    problems = tuple(_bundle_problem(tc.label, tc.scene, scenes.config.ba_points, rng) for tc in scenes.hidden[:2])
    inputs = []
    for k, pr in enumerate(problems):
        x = _x_of(pr)
        if k == 0:
            x = x + rng.normal(scale=0.01, size=x.shape)   # away from the start, where r2 matters too
        inputs.append((pr.K1, M1, pr.p1, pr.K2, pr.p2, x))
    return Bundle(problems, tuple(inputs))


# ------------------------------------------------------------------------------- Q6 multiview


@dataclass(frozen=True, eq=False)
class Step:
    """One call: the three cameras C (3, 3, 4), detections pts (3, 12, 3), Thres, and the truth."""

    label: str
    C: np.ndarray
    pts: np.ndarray
    Thres: int
    P_true: np.ndarray
    judged: np.ndarray        # (12,) bool: keypoints that count
    goal: float               # metres: mean distance goal (sequence) or per-point tolerance (probe)


@dataclass(frozen=True, eq=False)
class Multiview:
    sequence: tuple[Step, ...]
    probes: tuple[Step, ...]
    video: np.ndarray         # (T, 12, 3) for the plot


def _sequence(car, thres: int) -> tuple[Step, ...]:
    from solutions import MultiviewReconstruction

    steps = []
    for t in range(car.n_times):
        C, pts = car.C[t], car.pts[t]
        P_ref, _ = MultiviewReconstruction(C[0], pts[0], C[1], pts[1], C[2], pts[2], thres)
        judged = np.all(np.isfinite(P_ref), axis=1)
        ref_err = float(np.mean(np.linalg.norm(P_ref[judged] - car.P_true[t][judged], axis=1)))
        steps.append(Step(f"time step {t + 1}", np.array(C), np.array(pts), thres, car.P_true[t], judged,
                          jm.sequence_goal(ref_err)))
    return tuple(steps)


def _probe(car, t: int, thres: int, rng, label: str) -> Step:
    """Exact detections above Thres and clearly wrong ones at or below it, so that using a detection
    at exactly Thres (``>=``), ignoring the threshold, or leaving out one just above it each puts
    some keypoints off."""
    uv = car.uv_true[t]                                  # (3, 12, 2)
    n = uv.shape[1]
    groups = np.resize(np.array(["at", "below", "just_above", "control"]), n)
    rng.shuffle(groups)
    conf = np.zeros((3, n))
    xy = uv.copy()
    for k, group in enumerate(groups):
        high = rng.choice(np.arange(thres + 200, 1101, 100), size=3)
        conf[:, k] = high
        views = rng.permutation(3)
        odd, other = views[0], views[1]
        if group == "at":
            conf[odd, k] = thres
        elif group == "below":
            conf[odd, k] = rng.choice(np.arange(max(thres - 300, 100), thres, 100))
        elif group == "just_above":
            conf[other, k] = thres + 100
            conf[odd, k] = rng.choice(np.arange(max(thres - 300, 100), thres, 100))
        if group != "control":
            angle = rng.uniform(0, 2 * np.pi)
            xy[odd, k] += rng.uniform(40, 80) * np.array([np.cos(angle), np.sin(angle)])
    pts = np.concatenate([xy, conf[..., None]], axis=2)
    scale = max(1.0, float(np.abs(car.P_true[t]).max()))
    return Step(label, np.array(car.C[t]), pts, thres, car.P_true[t], np.ones(n, bool), 1e-5 * scale)


def prepare_multiview(scenes: Scenes) -> Multiview:
    rng = np.random.default_rng(scenes.config.seed("multiview"))
    sequence = _sequence(scenes.car, int(rng.choice([400, 500, 600])))
    probes = tuple(_probe(scenes.probe_car, t, int(rng.choice([500, 600, 700])), rng, f"threshold probe {t + 1}")
                   for t in range(2))
    return Multiview(sequence, probes, np.array(scenes.car.P_true, dtype=float))


# ------------------------------------------------------------------------------- all of them


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
