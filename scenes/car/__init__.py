"""Synthetic data for problem 6: a car crossing an intersection, seen by three cameras.

``make_car_scene(seed)`` builds, deterministically per seed, what ``data/q6`` holds in the
official handout (ten time steps, three cameras, twelve keypoints per view with a confidence)
together with the ground truth that the official data lacks; ``write_car`` writes it in the
official layout: ``cam{c}_time{t}.jpg`` and ``time{t}.npz`` with ``pts1..3`` (int64, (12, 3)
rows [x, y, confidence]), ``M1..3`` (float64 (3, 4)) and ``K1..3`` (float64 (3, 3)).

Frames and conventions
----------------------
- World: x east, y down (gravity), z north, metres; the ground is y = 0 and the centre of the
  intersection is the origin.  y points down so that ``cameras.look_at``'s default up vector
  and the official files' habit (cameras with R close to upright) both hold.
- Car frame: (forward, left, up), metres, origin on the ground under the middle of the car.
- M = [R | t] (3x4) maps world to camera coordinates, C = K M, pixels are (x, y) = (column, row).
- Keypoint order is ``core.skeleton.CAR_KEYPOINTS``: wheel hubs (outer face of each wheel),
  head- and taillights (centres of the lamps), roof corners.

Observation model (what makes the confidence threshold of Q6.1 matter)
----------------------------------------------------------------------
A keypoint hidden from a camera by the car itself (a ray test against the convex parts of the
body) gets a confidence of 300, 400 or 500.  A visible one gets 400 + 700 q plus noise,
rounded to a multiple of 100 and clipped to [500, 1100], where q is the cosine between the
direction to the camera and the best-facing surface normal at the keypoint, so grazing views
score lower.  The pixel error is isotropic Gaussian with a standard deviation that falls
geometrically from ``sigma_worst`` at 300 to ``sigma_best`` at 1100 (``confidence_sigma``),
then the pixel is rounded to integers.

Modules, each importing only those above it: ``model`` (the car, its keypoints), ``observe``
(visibility, confidence, noise), ``trajectory`` (the path and the cameras), ``street``, ``scene``
(the record), ``render`` (one view), ``make`` (``make_car_scene``), ``files`` (``write_car``).
"""

from __future__ import annotations

from .files import official_arrays, write_car
from .make import make_car_scene
from .model import CONFIDENCE_LEVELS, CarModel, car_keypoints, car_parts, car_rotation
from .observe import confidence_sigma
from .render import render_view
from .scene import CarScene

__all__ = [
    "CarModel",
    "CarScene",
    "CONFIDENCE_LEVELS",
    "confidence_sigma",
    "car_parts",
    "car_keypoints",
    "car_rotation",
    "make_car_scene",
    "render_view",
    "official_arrays",
    "write_car",
]
