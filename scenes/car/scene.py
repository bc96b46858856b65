"""The scene record: ground truth and observations of one seeded car sequence."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from scenes.painter import Layer

from .model import CarModel

# --------------------------------------------------------------------------------------------
# The scene
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class CarScene:
    """A generated problem-6 data set and its ground truth.

    Indices: t is the time step (0..T-1), c the camera (0..2 for the files' 1..3), k the
    keypoint (order ``CAR_KEYPOINTS``).

    Attributes
    ----------
    images : tuple of 3 tuples of T ndarrays (H, W, 3) uint8, or None
        ``images[c][t]`` is ``cam{c+1}_time{t}.jpg`` before JPEG compression; None when the
        scene was made with ``render=False``.
    K : ndarray, shape (T, 3, 3, 3)
        ``K[t, c]`` intrinsics (the file's ``K{c+1}``).
    M : ndarray, shape (T, 3, 3, 4)
        ``M[t, c]`` = [R | t] world to camera (the file's ``M{c+1}``).
    pts : ndarray, shape (T, 3, 12, 3), int64
        ``pts[t, c]`` is the file's ``pts{c+1}``: rows [x, y, confidence].
    P_true : ndarray, shape (T, 12, 3)
        True keypoints in world coordinates (metres).
    uv_true : ndarray, shape (T, 3, 12, 2)
        Exact projections of ``P_true``, (x, y) pixels, before noise and rounding.
    occluded : ndarray, shape (T, 3, 12), bool
        The keypoint is hidden from the camera by the car itself.
    car_position : ndarray, shape (T, 3)
        Origin of the car frame (on the ground under the middle of the car), world.
    car_heading : ndarray, shape (T,)
        Heading in radians (0 = +x, pi/2 = +z).
    model : CarModel
    width, height : int
        Image size in pixels.
    seed : int
    """

    images: tuple[tuple[np.ndarray, ...], ...] | None
    K: np.ndarray
    M: np.ndarray
    pts: np.ndarray
    P_true: np.ndarray
    uv_true: np.ndarray
    occluded: np.ndarray
    car_position: np.ndarray
    car_heading: np.ndarray
    model: CarModel
    width: int
    height: int
    seed: int
    street: tuple[Layer, Layer] = field(repr=False)

    @property
    def n_times(self) -> int:
        return int(self.pts.shape[0])

    @property
    def C(self) -> np.ndarray:
        """Camera matrices K M, shape (T, 3, 3, 4)."""
        return self.K @ self.M


def readonly(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a
