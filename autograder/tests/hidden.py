"""The scenes behind the hidden inputs: made in the grader, never shown to students.

Hidden temple scenes come from ``scenes.temple.make_temple_scene`` with seeds derived from the
instructor's secret (``GradingConfig.seed``), at the sizes and noise levels of the config; the
scene behind the kit's published data/ and, when present, the official course data are added.
The car sequence and the threshold probes of problem 6 come from ``scenes.car.make_car_scene``
(no images are rendered: the keypoint problem needs none).

Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera; C = K M; F maps points
of image 1 to lines of image 2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from autograder.config import GradingConfig
from starter.data import TempleData

__all__ = ["Scenes", "TempleCase", "TwoView", "make_scenes", "project", "skew", "symmetric_distances"]


@dataclass(frozen=True, eq=False)
class TempleCase:
    """A temple scene as the checks see it.

    label : how feedback names it ("hidden scene 1", "the default data", "the official data").
    scene : the TempleScene with ground truth, or None for the official data.
    official : the official data as ``starter.TempleData`` (no ground truth) when ``scene`` is None.
    """

    label: str
    scene: object = None
    official: TempleData | None = None

    @property
    def has_truth(self) -> bool:
        return self.scene is not None

    @property
    def pts1(self) -> np.ndarray:
        return self.scene.pts1.astype(float) if self.scene is not None else self.official.pts1

    @property
    def pts2(self) -> np.ndarray:
        return self.scene.pts2.astype(float) if self.scene is not None else self.official.pts2

    @property
    def K1(self) -> np.ndarray:
        return self.scene.K1 if self.scene is not None else self.official.K1

    @property
    def K2(self) -> np.ndarray:
        return self.scene.K2 if self.scene is not None else self.official.K2

    @property
    def M(self) -> float:
        return float(self.scene.M) if self.scene is not None else self.official.M


@dataclass(frozen=True, eq=False)
class TwoView:
    """Exact two-view data whose cameras have different intrinsics (so K1 and K2 cannot be mixed up).

    K1, K2 : (3, 3); M2 : (3, 4) true [R | t] with |t| = 1; X : (N, 3) world points in front of
    both cameras; pts1, pts2 : (N, 2) exact projections; F : (3, 3) true F, unit norm.
    """

    K1: np.ndarray
    K2: np.ndarray
    M2: np.ndarray
    X: np.ndarray
    pts1: np.ndarray
    pts2: np.ndarray
    F: np.ndarray

    @property
    def C1(self) -> np.ndarray:
        return self.K1 @ np.hstack([np.eye(3), np.zeros((3, 1))])

    @property
    def C2(self) -> np.ndarray:
        return self.K2 @ self.M2


@dataclass(frozen=True, eq=False)
class Scenes:
    """Every scene the hidden inputs are cut from (see the module docstring)."""

    config: GradingConfig
    hidden: tuple[TempleCase, ...]
    default: TempleCase | None
    official: TempleCase | None
    car: object
    probe_car: object
    two_view: TwoView

    def temple_cases(self, *, official: bool = True, default: bool = True) -> list[TempleCase]:
        """Hidden scenes first, then the default data and the official data when wanted and present."""
        out = list(self.hidden)
        if default and self.default is not None:
            out.append(self.default)
        if official and self.official is not None:
            out.append(self.official)
        return out


def make_scenes(config: GradingConfig) -> Scenes:
    """Render the hidden temple scenes and make the car scenes of ``config`` (a few seconds)."""
    from scenes.car import make_car_scene
    from scenes.temple import make_temple_scene

    hidden = tuple(
        TempleCase(f"hidden scene {k}", make_temple_scene(
            config.seed(f"temple-{k}"), width=spec.width, height=spec.height, noise_px=spec.noise_px))
        for k, spec in enumerate(config.temples, start=1))
    default = None
    if config.use_default_data:
        from scenes.defaults import default_temple

        default = TempleCase("the default data", default_temple())
    official = None
    folder = config.official_dir()
    if folder is not None:
        from starter import load_temple

        official = TempleCase("the official data", None, load_temple(folder))
    car = make_car_scene(config.seed("car") % 2**32, n_times=config.car_times, render=False)
    probe_car = make_car_scene(config.seed("car-probe") % 2**32, n_times=2, render=False)
    return Scenes(config, hidden, default, official, car, probe_car, _two_view(hidden[-1].scene))


def _two_view(scene) -> TwoView:
    # The temple's geometry, with a camera 2 whose focal length and principal point differ from
    # camera 1's, and t scaled to unit length (the scale that camera2 returns).
    K1 = scene.K1.copy()
    K2 = K1.copy()
    K2[0, 0] *= 1.07
    K2[1, 1] *= 1.05
    K2[0, 2] += 0.03 * scene.width
    K2[1, 2] -= 0.02 * scene.height
    scale = np.linalg.norm(scene.t)
    M2 = np.hstack([scene.R, (scene.t / scale)[:, None]])
    X = scene.X / scale
    C1 = K1 @ np.hstack([np.eye(3), np.zeros((3, 1))])
    F = np.linalg.inv(K2).T @ skew(M2[:, 3]) @ M2[:, :3] @ np.linalg.inv(K1)
    return TwoView(K1, K2, M2, X, project(C1, X), project(K2 @ M2, X), F / np.linalg.norm(F))


# ------------------------------------------------------------------------------- geometry


def project(C: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) of points X (N, 3) through C (3, 4); NaN where the depth is zero."""
    with np.errstate(all="ignore"):  # student points may be huge or NaN; they just come out wrong
        h = np.asarray(X, float) @ C[:, :3].T + C[:, 3]
        return h[:, :2] / h[:, 2:]


def skew(v) -> np.ndarray:
    """[v]x (3, 3), so that skew(v) @ w == cross(v, w)."""
    x, y, z = np.asarray(v, float).reshape(3)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def symmetric_distances(F: np.ndarray, pts1: np.ndarray, pts2: np.ndarray) -> np.ndarray:
    """Symmetric epipolar distances (2N,): x2 to the line F x1, and x1 to the line F^T x2 (pixels).

    Invariant to the scale and sign of F; inf where a line is undefined or F is not finite.
    """
    F = np.asarray(F, float)
    if F.shape != (3, 3) or not np.all(np.isfinite(F)) or not np.any(F):
        return np.full(2 * len(pts1), np.inf)
    h1 = np.column_stack([pts1, np.ones(len(pts1))])
    h2 = np.column_stack([pts2, np.ones(len(pts2))])
    l2 = h1 @ F.T
    l1 = h2 @ F
    num = np.abs(np.sum(h2 * l2, axis=1))
    with np.errstate(divide="ignore", invalid="ignore"):
        d2 = num / np.hypot(l2[:, 0], l2[:, 1])
        d1 = num / np.hypot(l1[:, 0], l1[:, 1])
    d = np.concatenate([d2, d1])
    return np.where(np.isfinite(d), d, np.inf)
