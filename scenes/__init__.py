"""Seeded synthetic scenes with ground truth: the kit's default data and unseen variants.

- :mod:`scenes.temple`: a textured temple on its side seen by two calibrated cameras
  (problems 2-5), with matches, wrong matches and templeCoords, in the official file format.
- :mod:`scenes.car`: a car crossing an intersection seen by three cameras over ten time steps
  (problem 6), with keypoint detections and confidences.
- :mod:`scenes.cameras`: the scene-building camera helpers both share (intrinsics, look_at,
  rotation_about; M = [R | t] maps world to camera).  Projection, depths, F and E are
  core.geometry's.
- :mod:`scenes.defaults`: the seeds and writer of data/.

``python -m kit data`` rewrites data/ from these.
"""

from .cameras import intrinsics, look_at, projection, rotation_about
from .car import CarScene, make_car_scene, write_car
from .temple import TempleScene, make_temple_scene, write_temple

__all__ = [
    "TempleScene", "make_temple_scene", "write_temple", "CarScene", "make_car_scene", "write_car",
    "intrinsics", "look_at", "projection", "rotation_about",
]
