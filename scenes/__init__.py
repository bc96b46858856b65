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

import importlib
import importlib.util

# name -> the submodule that defines it.  They load on first use (PEP 562): a notebook that imports
# only scenes.cameras must not pay for the temple renderer's scipy.ndimage and scipy.spatial (0.1 to
# 0.3 s in every kernel and in every sandboxed process that loads a student's notebooks).
_HOMES = {
    "TempleScene": "temple", "make_temple_scene": "temple", "write_temple": "temple",
    "CarScene": "car", "make_car_scene": "car", "write_car": "car",
    "intrinsics": "cameras", "look_at": "cameras", "projection": "cameras", "rotation_about": "cameras",
}
__all__ = list(_HOMES)


def __getattr__(name: str):
    if name in _HOMES:
        return getattr(importlib.import_module(f"{__name__}.{_HOMES[name]}"), name)
    if importlib.util.find_spec(f"{__name__}.{name}") is not None:  # scenes.temple after `import scenes`
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
