"""Camera helpers for building the synthetic scenes (intrinsics, look_at, rotation_about).

Conventions (the same as the homework's):
- M = [R | t] (3x4) maps world coordinates to camera coordinates: X_cam = R @ X + t.
- C = K @ M (3x4) maps homogeneous world points to homogeneous pixels.
- A pixel is (x, y) = (column, row); the camera looks along +z, x to the right, y down.
"""

from __future__ import annotations

import numpy as np

# project, depths and camera_center live in core.geometry; they are re-exported here because the
# notebooks and tests import them from scenes.cameras.
from core.geometry import camera_center, depths, project, skew

__all__ = ["intrinsics", "look_at", "projection", "project", "depths", "camera_center", "rotation_about"]


def intrinsics(f: float, cx: float, cy: float, fy: float | None = None) -> np.ndarray:
    """Return K (3x3) for focal lengths f (x) and fy (y, default f) and principal point (cx, cy) in pixels."""
    return np.array([[f, 0.0, cx], [0.0, f if fy is None else fy, cy], [0.0, 0.0, 1.0]])


def look_at(center, target, up=(0.0, -1.0, 0.0)) -> np.ndarray:
    """Return M = [R | t] (3x4) of a camera at ``center`` (3,) looking at ``target`` (3,).

    ``up`` (3,) is the world direction that should appear upwards in the image (towards
    smaller y).  Raises ValueError when it is parallel to the viewing direction.
    """
    c = np.asarray(center, float)
    z = np.asarray(target, float) - c
    z /= np.linalg.norm(z)
    up = np.asarray(up, float)
    x = np.cross(-up, z)  # image x points right when image y (down) is -up
    n = np.linalg.norm(x)
    if n < 1e-9:
        raise ValueError("look_at: up is parallel to the viewing direction")
    x /= n
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    return np.hstack([R, (-R @ c)[:, None]])


def projection(K: np.ndarray, M: np.ndarray) -> np.ndarray:
    """C = K @ M (3x4)."""
    return np.asarray(K, float) @ np.asarray(M, float)


def rotation_about(axis, angle: float) -> np.ndarray:
    """Rotation matrix (3x3) of ``angle`` radians about the unit vector ``axis`` (3,)."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    K = skew(a)
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
