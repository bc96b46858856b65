"""Q3.1: the essential matrix from F and the intrinsics."""

from __future__ import annotations

from core.validate import as_matrix

__all__ = ["essentialMatrix"]


def essentialMatrix(F, K1, K2):
    """The essential matrix of the camera pair, from F and the two intrinsics.

    Parameters
    ----------
    F : (3, 3) fundamental matrix in pixels, x2^T F x1 = 0.
    K1, K2 : (3, 3) intrinsics of camera 1 and camera 2.

    Returns
    -------
    E : (3, 3) essential matrix, x2n^T E x1n = 0 for normalised points xn = K^-1 x.  Same
        scale and sign ambiguity as F; its two non-zero singular values are equal only up to
        the noise in F.

    Method (answer key only)
    ------------------------
    Substituting x = K xn in x2^T F x1 = 0 gives E = K2^T F K1.
    """
    F = as_matrix(F, "F", (3, 3))
    K1 = as_matrix(K1, "K1", (3, 3))
    K2 = as_matrix(K2, "K2", (3, 3))
    return K2.T @ F @ K1
