"""The data the public checks run on: generated scenes with known answers, and the default data.

Generated data comes from the kit's scene generator with a fixed, public seed, made once per
session (about a second).  The two-view data reuse the generated temple's 3D points and
cameras at the official scale (640 x 480, M = 640, products of coordinates above 65535), with
a camera 2 whose intrinsics differ from camera 1's, so that K1 and K2 cannot be confused
unnoticed.  The default data is whatever ``starter.load_temple`` / ``load_car_frame`` find; it
has no ground truth: the checks that would need a reference answer to use it (an F, a pose)
leave it out.  Nothing here uses OpenCV, so the checks are the same with and without it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from core.geometry import CameraPair, eightpoint_scale

__all__ = [
    "PUBLIC_SEED",
    "NO_DEFAULT_DATA",
    "NoisyPair",
    "car_data_or_note",
    "car_frame",
    "noisy_pair",
    "temple_data_or_note",
    "temple_scene",
    "triangulation_goal",
    "two_view",
]

PUBLIC_SEED = 720
_NOISE_PX = 0.5


@dataclass(frozen=True, eq=False)
class NoisyPair:
    """A camera pair with known answers and the noisy matches a check needs.

    pair : core.geometry.CameraPair (K1, K2, M2, X and every derived truth: C1, C2, pts1, pts2, E, F).
    pts1_u16, pts2_u16 : (N, 2) uint16, the projections plus noise, rounded (the data files' form).
    M : the scale parameter, max(width, height).
    """

    pair: CameraPair
    pts1_u16: np.ndarray
    pts2_u16: np.ndarray
    M: float


def noisy_pair(scene) -> NoisyPair:
    """The NoisyPair of a TempleScene (its cameras, true points and stored uint16 matches)."""
    return NoisyPair(scene.pair, np.asarray(scene.pts1), np.asarray(scene.pts2), scene.M)


@lru_cache(maxsize=1)
def temple_scene():
    """The generated temple pair (320 x 240, rendered) the image checks use; made once."""
    from scenes.temple import make_temple_scene

    return make_temple_scene(PUBLIC_SEED, width=320, height=240, n_corresp=60, n_outliers=0,
                             n_coords=60, supersample=1)


@lru_cache(maxsize=1)
def two_view() -> NoisyPair:
    """The generated temple's geometry seen by 640 x 480 cameras with K1 != K2 (see module doc)."""
    s = temple_scene()
    K1 = np.diag([2.0, 2.0, 1.0]) @ s.K1
    K2 = K1.copy()
    K2[0, 0] *= 1.04
    K2[1, 1] *= 1.04
    K2[:2, 2] += [7.0, -5.0]
    pair = CameraPair(K1, K2, s.M2.copy(), s.X.copy())
    rng = np.random.default_rng(PUBLIC_SEED)

    def stored(p):
        return np.rint(p + rng.normal(0.0, _NOISE_PX, p.shape)).astype(np.uint16)

    return NoisyPair(pair, stored(pair.pts1), stored(pair.pts2), eightpoint_scale(640, 480))


@lru_cache(maxsize=1)
def car_frame():
    """(C (3, 3, 4), P_true (12, 3)) of one generated time step of the car scene (no images)."""
    from scenes.car import make_car_scene

    scene = make_car_scene(PUBLIC_SEED, n_times=1, render=False)
    return scene.C[0].copy(), scene.P_true[0].copy()


def temple_data_or_note(root=None):
    """(TempleData or None, note): the temple data ``starter.load_temple(root)`` finds, or why there is none.

    Not the scene behind data/ (that is ``scenes.defaults.default_temple``, with its ground truth).
    """
    from starter.data import load_temple

    try:
        return load_temple(root), ""
    except FileNotFoundError:
        return None, "no temple data found in data/ (or $HW4_DATA): checked on generated scenes only"
    except ValueError as exc:
        return None, f"the temple data could not be read ({exc}): checked on generated scenes only"


def car_data_or_note(root=None):
    """(CarFrame of the data's first time step or None, note): what ``starter.load_car_frame`` finds.

    Not the scene behind data/q6 (that is ``scenes.defaults.default_car``).
    """
    from starter.data import car_times, load_car_frame

    try:
        return load_car_frame(car_times(root)[0], root, images=False), ""
    except FileNotFoundError:
        return None, "no car data found in data/q6: checked on a generated scene only"
    except ValueError as exc:
        return None, f"the car data could not be read ({exc}): checked on a generated scene only"


# The default data have no cameras, no F and no true points of their own: only the checks that
# need none of them (eightpoint, essentialMatrix with the data's intrinsics, MultiviewReconstruction)
# use them.  The others would need a reference answer (an F, a pose) to start from; the checks
# use none, and no OpenCV either, so that they are the same wherever they run.
NO_DEFAULT_DATA = ("the default data are not used by this check: they come with no cameras or F, and the "
                   "checks use no reference answer (nor OpenCV) to make them")


def triangulation_goal(C1, pts1, C2, pts2, *starts) -> float:
    """The total squared reprojection error (pixels^2) a triangulation of the matches (N, 2) with
    C1, C2 (3, 4) can reach: judging.triangulation.optimal_error polished from ``starts`` (N, 3)
    (the true points, the student's own; malformed ones are skipped)."""
    from judging.triangulation import optimal_error

    n = len(np.asarray(pts1))
    good = []
    for X in starts:
        try:
            X = np.asarray(X, dtype=float)
        except (TypeError, ValueError):
            continue
        if X.shape == (n, 3):
            good.append(X)
    return optimal_error(C1, pts1, C2, pts2, *good)
