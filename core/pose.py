"""``camera2``: the four camera-2 extrinsics compatible with an essential matrix.

Given to students as ``starter.camera2`` (``starter`` and ``starter.pose`` re-export it);
``judging`` uses it from here, below ``starter``.  numpy only.
"""

from __future__ import annotations

import numpy as np

from core.validate import DegenerateInputError, as_matrix

__all__ = ["camera2"]

_W = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def camera2(E) -> np.ndarray:
    """The four candidate extrinsics M2 = [R | t] of camera 2, given E and M1 = [I | 0].

    Parameters
    ----------
    E : (3, 3) essential matrix, x2n^T E x1n = 0 for normalised image points (K^-1 x).

    Returns
    -------
    M2s : (3, 4, 4) array; candidate i is ``M2s[:, :, i]``, a 3x4 [R | t] mapping camera-1
        (world) coordinates to camera-2 coordinates.  R is a proper rotation (det +1) and
        |t| = 1: E fixes the translation only up to scale and sign.  Exactly one candidate puts
        the scene in front of both cameras; choosing it is the job of ``findM2``.
    """
    E = as_matrix(E, "E", (3, 3))
    U, S, Vt = np.linalg.svd(E)
    if S[0] <= 0 or S[1] / S[0] < 1e-8:
        raise DegenerateInputError(
            f"E: an essential matrix has two equal non-zero singular values; got {S} (rank below 2)")
    # Flipping a sign of U or V^T leaves E's line of solutions unchanged and makes the R's proper.
    if np.linalg.det(U) < 0:
        U = -U
    if np.linalg.det(Vt) < 0:
        Vt = -Vt
    t = U[:, 2]
    Ra, Rb = U @ _W @ Vt, U @ _W.T @ Vt
    M2s = np.empty((3, 4, 4))
    for i, (R, s) in enumerate([(Ra, 1), (Ra, -1), (Rb, 1), (Rb, -1)]):
        M2s[:, :, i] = np.hstack([R, s * t[:, None]])
    return M2s
