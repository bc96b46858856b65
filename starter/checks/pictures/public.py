"""The public data the figures are drawn on, and its truth when the data is the kit's default.

The student side (``public_outputs``) and the trusted side (``draw``) both read the data here:
the temple pair and the car's first time step, from data/ (or ``root``, or $HW4_DATA).  Only
the default data (scenes.defaults, seed 75 for the temple, 0 for the car) has a known truth: it
is regenerated from the seed, and used only when the files on disk are exactly the seed's (an
instructor's official data is used as it is, with no truth: the figures say so).  Hidden scenes
are never used.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = ["NO_TRUTH", "CarPublic", "TemplePublic", "car", "need_truth", "temple"]

NO_TRUTH = "no ground truth for this data (not the kit's default data)"


@dataclass(frozen=True, eq=False)
class TemplePublic:
    """The temple pair as a student loads it, and its truth when known.

    data : starter.data.TempleData (images uint8 (H, W, 3); points float (N, 2) pixels (x, y)).
    scene : scenes.temple.TempleScene of the default data (true cameras C1, C2 (3, 4), M2 [R | t]
        (3, 4) world -> camera 2, F_true (3, 3) with x2^T F x1 = 0, true points X (N, 3),
        exact matches pts1_true, pts2_true (N, 2), templeCoords truth X_coords (P, 3), x2_true (P, 2)),
        or None when the data is not the default data.
    """

    data: object
    scene: object | None


@dataclass(frozen=True, eq=False)
class CarPublic:
    """The car's first time step as a student loads it, and its truth when known.

    frame : starter.data.CarFrame (pts: three (12, 3) [x, y, confidence]; C: three (3, 4)).
    P_true : (12, 3) the true keypoints (world coordinates), or None when not the default data.
    """

    frame: object
    P_true: np.ndarray | None


def _same(a, b) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a.shape == b.shape and bool(np.array_equal(a, b))


@lru_cache(maxsize=1)
def _default_temple_scene():
    from scenes.defaults import default_temple

    return default_temple()


def temple(root=None, *, truth: bool = True) -> TemplePublic:
    """The public temple pair of ``root`` (default data/ or $HW4_DATA), with its truth when it is the
    default data and ``truth`` is asked for (regenerating it takes about 3 s, once)."""
    from starter.data import load_temple

    data = load_temple(root)
    scene = None
    if truth:
        s = _default_temple_scene()
        if (_same(data.pts1, s.pts1) and _same(data.pts2, s.pts2) and _same(data.K1, s.K1)
                and _same(data.x1, np.ravel(s.x1)) and data.im1.shape == s.im1.shape):
            scene = s
    return TemplePublic(data, scene)


def car(root=None, *, truth: bool = True) -> CarPublic:
    """The public car's first time step of ``root``, with the true keypoints when it is the default data."""
    from starter.data import car_times, load_car_frame

    frame = load_car_frame(car_times(root)[0], root, images=False)
    P_true = None
    if truth and frame.time == 0:
        from scenes.defaults import default_car

        scene = default_car(render=False)
        if all(_same(frame.pts[i], scene.pts[0][i]) for i in range(3)):
            P_true = np.array(scene.P_true[0], float)
    return CarPublic(frame, P_true)


def need_truth(pub, question: str):
    """``pub``'s truth (scene or P_true), or ValueError saying that ``question``'s figure needs the default data."""
    truth = pub.scene if isinstance(pub, TemplePublic) else pub.P_true
    if truth is None:
        raise ValueError(f"{question}'s figure needs the ground truth of the kit's default data (its cameras, F and "
                         f"true points); {NO_TRUTH} "
                         "(restore data/ with `python -m kit data` to see it)")
    return truth
