"""The scenes behind the hidden inputs: made in the grader, never shown to students (``make_scenes``).

Hidden temple scenes come from ``scenes.temple.make_temple_scene`` with seeds derived from the
instructor's secret (``GradingConfig.seed``), at the sizes and noise levels of the config; the
scene behind the kit's published data/ and, when present, the official course data are added.
The car sequence and the threshold probes of problem 6 come from ``scenes.car.make_car_scene``
(no images are rendered: the keypoint problem needs none).

A *salt* (a digest of one submission's code, ``autograder.inputs.build.code_salt``) makes the
draw of that submission: every seed of the hidden temples, the cars and the checks' own random
choices (``Scenes.seed``) then derives from the secret and the salt.  The default data and the
official data are the same for every draw (``FIXED_LABELS``); ``make_scenes(..., fixed=False)``
leaves them out, as a batch makes what depends on them once.

Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera; C = K M; F maps points
of image 1 to lines of image 2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from autograder.inputs.config import GradingConfig
from core.geometry import CameraPair
from starter.data import TempleData

__all__ = ["DEFAULT_LABEL", "FIXED_LABELS", "OFFICIAL_LABEL", "Scenes", "TempleCase", "make_scenes"]

DEFAULT_LABEL, OFFICIAL_LABEL = "the default data", "the official data"
FIXED_LABELS = (DEFAULT_LABEL, OFFICIAL_LABEL)   # the scenes no salt changes


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
        return self.scene.M if self.scene is not None else self.official.M


@dataclass(frozen=True, eq=False)
class Scenes:
    """Every scene the hidden inputs are cut from (see the module docstring)."""

    config: GradingConfig
    hidden: tuple[TempleCase, ...]
    default: TempleCase | None
    official: TempleCase | None
    car: object
    probe_car: object
    two_view: CameraPair      # exact data whose cameras have different intrinsics, |t| = 1
    salt: str | None = None   # the submission's code digest of this draw; None: the secret's own

    def seed(self, label: str) -> int:
        """The seed of the random input ``label`` in this draw (63-bit; ``config.seed`` when unsalted)."""
        return _seed(self.config, self.salt, label)

    def temple_cases(self, *, official: bool = True, default: bool = True) -> list[TempleCase]:
        """Hidden scenes first, then the default data and the official data when wanted and present."""
        out = list(self.hidden)
        if default and self.default is not None:
            out.append(self.default)
        if official and self.official is not None:
            out.append(self.official)
        return out


def make_scenes(config: GradingConfig, *, salt: str | None = None, fixed: bool = True) -> Scenes:
    """Render the hidden temple scenes and make the car scenes of ``config`` (a few seconds).

    salt : None (the draw of the secret alone) or a non-empty str, the submission's code digest
        whose draw this is.
    fixed : also add the default data's scene and the official data (they do not depend on the
        salt); False leaves them out (``default`` and ``official`` are None).
    """
    from scenes.car import make_car_scene
    from scenes.temple import make_temple_scene

    if salt is not None and (not isinstance(salt, str) or not salt):
        raise ValueError(f"salt: expected None or a non-empty str, got {salt!r}")
    hidden = tuple(
        TempleCase(f"hidden scene {k}", make_temple_scene(
            _seed(config, salt, f"temple-{k}"), width=spec.width, height=spec.height, noise_px=spec.noise_px))
        for k, spec in enumerate(config.temples, start=1))
    default = None
    if fixed and config.use_default_data:
        from scenes.defaults import default_temple

        default = TempleCase(DEFAULT_LABEL, default_temple())
    official = None
    folder = config.official_dir() if fixed else None
    if folder is not None:
        from starter import load_temple

        official = TempleCase(OFFICIAL_LABEL, None, load_temple(folder))
    car = make_car_scene(_seed(config, salt, "car") % 2**32, n_times=config.car_times, render=False)
    probe_car = make_car_scene(_seed(config, salt, "car-probe") % 2**32, n_times=2, render=False)
    return Scenes(config, hidden, default, official, car, probe_car, _two_view(hidden[-1].scene), salt)


def _seed(config: GradingConfig, salt: str | None, label: str) -> int:
    # Unsalted labels are the secret's own seeds as before; a salt makes every label another.
    return config.seed(label if salt is None else f"{label}\x00draw\x00{salt}")


def _two_view(scene) -> CameraPair:
    # The temple's geometry, with a camera 2 whose focal length and principal point differ from
    # camera 1's, and t scaled to unit length (the scale that camera2 returns).
    K2 = scene.K1.copy()
    K2[0, 0] *= 1.07
    K2[1, 1] *= 1.05
    K2[0, 2] += 0.03 * scene.width
    K2[1, 2] -= 0.02 * scene.height
    return CameraPair(scene.K1.copy(), K2, scene.M2, scene.X).unit_baseline()
