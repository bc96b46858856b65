"""Rotation parameterisation for bundle adjustment: ``rodrigues`` and ``invRodrigues``.

A rotation vector r (3,) has direction = the rotation axis and norm = the angle in radians.
Both directions are delegated to scipy.spatial.transform.Rotation, which handles the angles near 0
and near pi where hand-written formulas lose precision.  scipy is imported when a function is
first called, never when the module is: core is imported by every process of the kit (the
sandbox's children and ``judging`` among them) and must stay light.

Given to students as ``starter.rodrigues`` / ``starter.invRodrigues`` (``starter`` re-exports
them); ``judging`` uses them from here, below ``starter``.
"""

from __future__ import annotations

import numpy as np

from core.validate import as_matrix

__all__ = ["rodrigues", "invRodrigues"]


def rodrigues(r) -> np.ndarray:
    """Rotation matrix R (3x3) of the rotation vector r (3,) (axis times angle in radians)."""
    arr = np.asarray(r, dtype=float).reshape(-1) if np.size(r) == 3 else None
    if arr is None:
        raise ValueError(f"r: expected 3 numbers (a rotation vector), got shape {np.shape(r)}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("r: expected finite values, got NaN or inf")
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(arr).as_matrix()


def invRodrigues(R) -> np.ndarray:
    """Rotation vector r (3,) of the rotation matrix R (3x3); |r| is the angle in [0, pi].

    R must be a rotation (orthonormal, det = +1) to about 1e-6; a matrix that is not raises a
    ValueError rather than silently returning the vector of some other rotation.
    """
    R = as_matrix(R, "R", (3, 3))
    err = np.abs(R @ R.T - np.eye(3)).max()
    det = np.linalg.det(R)
    if err > 1e-6 or det < 0:
        raise ValueError(f"R: expected a rotation matrix (R R^T = I, det +1), got |R R^T - I| = {err:.2g}, det = {det:.3g}")
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_rotvec()
