"""Geometry primitives of two-view reconstruction, written once for the whole kit.

Conventions (the homework's):
- a pixel is (x, y) = (column, row); point arrays are (N, 2) pixels unless stated otherwise;
- M = [R | t] (3x4) maps world coordinates to camera coordinates: X_cam = R X + t; camera 1 is
  M1 = [I | 0], so world coordinates are camera-1 coordinates;
- C = K M (3x4) maps homogeneous world points to homogeneous pixels;
- F (3x3) maps a point x1 of image 1 to its epipolar line l2 = F x1 in image 2: x2^T F x1 = 0;
  E = [t]x R, and F = K2^-T E K1^-1.

These functions take arrays as they come and never raise on odd values: NaN or inf come out
where a projection or a line is undefined, so they serve the scene generator, the reference,
the self-checks and the grader (whose inputs may be a student's garbage) alike.  Checking a
student's input belongs to ``core.validate``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "CameraPair",
    "IDENTITY_POSE",
    "depths",
    "eightpoint_scale",
    "camera_center",
    "enforce_rank2",
    "essential_from_pose",
    "fundamental_from_pose",
    "homogeneous",
    "epipolar_distances",
    "project",
    "similarity_align", "similarity_fit",
    "skew",
    "symmetric_epipolar_cost_of",
    "symmetric_epipolar_distances",
]

IDENTITY_POSE = np.hstack([np.eye(3), np.zeros((3, 1))])
IDENTITY_POSE.flags.writeable = False


def eightpoint_scale(width, height) -> float:
    """The homework's scale M = max(width, height) of an image (pixels), as a float.

    ``eightpoint(pts1, pts2, M)`` divides the pixel coordinates by M.  For an image array of
    shape (height, width[, channels]): ``eightpoint_scale(shape[1], shape[0])``.
    """
    return float(max(width, height))


def homogeneous(pts) -> np.ndarray:
    """(N, 2) points -> (N, 3) homogeneous points with a last coordinate of 1 (float)."""
    p = np.asarray(pts, float)
    return np.hstack([p, np.ones((len(p), 1))])


def skew(v) -> np.ndarray:
    """[v]x (3, 3) of a 3-vector v, so that skew(v) @ w == np.cross(v, w)."""
    x, y, z = np.asarray(v, float).reshape(3)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def project(C, X) -> np.ndarray:
    """Pixels (N, 2) of world points X (N, 3) through the camera matrix C (3x4).

    NaN or inf where a point has depth zero; no warning is raised for it.
    """
    C = np.asarray(C, float)
    with np.errstate(all="ignore"):
        h = np.asarray(X, float).reshape(-1, 3) @ C[:, :3].T + C[:, 3]
        return h[:, :2] / h[:, 2:3]


def depths(M, X) -> np.ndarray:
    """Depth (N,) of world points X (N, 3) along the optical axis of the camera M = [R | t] (3x4)."""
    M = np.asarray(M, float)
    return np.asarray(X, float).reshape(-1, 3) @ M[2, :3] + M[2, 3]


def camera_center(M) -> np.ndarray:
    """World position (3,) of the centre of the camera M = [R | t] (3x4): -R^T t."""
    M = np.asarray(M, float)
    return -M[:, :3].T @ M[:, 3]


def essential_from_pose(M2) -> np.ndarray:
    """E = [t]x R (3x3) of camera 2 at M2 = [R | t] (3x4) relative to camera 1 at [I | 0], at t's scale."""
    M2 = np.asarray(M2, float)
    return skew(M2[:, 3]) @ M2[:, :3]


def fundamental_from_pose(K1, K2, M2) -> np.ndarray:
    """The true F (3x3, pixels, unit Frobenius norm) of cameras K1 [I | 0] and K2 M2.

    F = K2^-T [t]x R K1^-1 maps a pixel of image 1 to its epipolar line in image 2.
    """
    F = np.linalg.inv(np.asarray(K2, float)).T @ essential_from_pose(M2) @ np.linalg.inv(np.asarray(K1, float))
    return F / np.linalg.norm(F)


def _lines_and_residuals(F, pts1, pts2):
    h1, h2 = homogeneous(pts1), homogeneous(pts2)
    l2 = h1 @ np.asarray(F, float).T  # lines in image 2, one per x1
    l1 = h2 @ np.asarray(F, float)  # lines in image 1, one per x2
    return l1, l2, np.abs(np.sum(h2 * l2, axis=1))


def epipolar_distances(F, pts1, pts2) -> np.ndarray:
    """Distance in pixels (N,) of each x2 (pts2, (N, 2)) to its epipolar line F x1 in image 2.

    Invariant to the scale and sign of F; inf where the line is undefined (F x1 has no direction)
    or F is not finite.
    """
    F = np.asarray(F, float)
    n = len(pts1)
    if F.shape != (3, 3) or not np.all(np.isfinite(F)) or not np.any(F):
        return np.full(n, np.inf)
    _, l2, r = _lines_and_residuals(F, pts1, pts2)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = r / np.hypot(l2[:, 0], l2[:, 1])
    return np.where(np.isfinite(d), d, np.inf)


def symmetric_epipolar_distances(F, pts1, pts2) -> np.ndarray:
    """Both epipolar distances in pixels (2N,): x2 to the line F x1, then x1 to the line F^T x2.

    Invariant to the scale and sign of F; inf where a line is undefined or F is not finite.
    """
    F = np.asarray(F, float)
    n = len(pts1)
    if F.shape != (3, 3) or not np.all(np.isfinite(F)) or not np.any(F):
        return np.full(2 * n, np.inf)
    l1, l2, r = _lines_and_residuals(F, pts1, pts2)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.concatenate([r / np.hypot(l2[:, 0], l2[:, 1]), r / np.hypot(l1[:, 0], l1[:, 1])])
    return np.where(np.isfinite(d), d, np.inf)


def enforce_rank2(F) -> np.ndarray:
    """The rank-2 matrix closest to F (3x3) in Frobenius norm: its smallest singular value set to 0."""
    U, S, Vt = np.linalg.svd(np.asarray(F, dtype=float))
    S[2] = 0.0
    return (U * S) @ Vt


def symmetric_epipolar_cost_of(pts1, pts2):
    """The function ``F -> float`` (F: (3, 3) finite) giving the sum over the matches ``pts1``,
    ``pts2`` ((N, 2) each) of both squared epipolar distances (pixels^2; those of
    ``symmetric_epipolar_distances``), inf where a line is undefined.

    For an optimiser, which evaluates it thousands of times: the points are made homogeneous once
    and the squared distances are never square-rooted, which makes an evaluation about 40 % faster.
    """
    h1, h2 = homogeneous(pts1), homogeneous(pts2)

    def cost(F) -> float:
        l2 = h1 @ F.T
        l1 = h2 @ F
        r2 = np.einsum("ij,ij->i", h2, l2) ** 2
        # The array methods and math.isfinite do what np.sum and np.isfinite do, bit for bit,
        # without their dispatch, which was a tenth of an evaluation.
        with np.errstate(divide="ignore", invalid="ignore"):
            total = float((r2 / (l2[:, 0] ** 2 + l2[:, 1] ** 2)).sum() + (r2 / (l1[:, 0] ** 2 + l1[:, 1] ** 2)).sum())
        return total if math.isfinite(total) else np.inf

    return cost


@dataclass(frozen=True, eq=False)
class CameraPair:
    """Two calibrated cameras and the world points they see, with every derived ground truth.

    K1, K2 : (3, 3) intrinsics, pixels.
    M2 : (3, 4) [R | t] of camera 2 (world = camera-1 coordinates, M1 = [I | 0]).
    X : (N, 3) world points, in front of both cameras.

    Derived (exact, noise-free): M1, C1, C2 (3x4), pts1, pts2 (N, 2) pixel projections,
    E (3x3, [t]x R at t's scale) and F (3x3 pixels, unit norm, x2^T F x1 = 0).
    """

    K1: np.ndarray
    K2: np.ndarray
    M2: np.ndarray
    X: np.ndarray

    @property
    def M1(self) -> np.ndarray:
        return IDENTITY_POSE.copy()

    @property
    def C1(self) -> np.ndarray:
        return np.asarray(self.K1, float) @ IDENTITY_POSE

    @property
    def C2(self) -> np.ndarray:
        return np.asarray(self.K2, float) @ np.asarray(self.M2, float)

    @property
    def pts1(self) -> np.ndarray:
        return project(self.C1, self.X)

    @property
    def pts2(self) -> np.ndarray:
        return project(self.C2, self.X)

    @property
    def E(self) -> np.ndarray:
        return essential_from_pose(self.M2)

    @property
    def F(self) -> np.ndarray:
        return fundamental_from_pose(self.K1, self.K2, self.M2)

    def unit_baseline(self) -> CameraPair:
        """The same pair with |t| = 1 and X scaled with it (the scale ``camera2`` returns)."""
        s = float(np.linalg.norm(np.asarray(self.M2, float)[:, 3]))
        M2 = np.array(self.M2, float)
        M2[:, 3] /= s
        return CameraPair(self.K1, self.K2, M2, np.asarray(self.X, float) / s)


def similarity_fit(A, B):
    """(s, R, t): the similarity (scale s > 0, rotation R (3, 3), shift t (3,)) that minimises
    sum |s R a + t - b|^2 over the rows of A, B (N, 3) (Umeyama's closed form, no reflection);
    a point a moves to ``s * R @ a + t``.  None when A or B is not finite, their lengths differ or
    A has no extent.
    """
    A, B = np.asarray(A, float).reshape(-1, 3), np.asarray(B, float).reshape(-1, 3)
    if len(A) != len(B) or len(A) == 0 or not (np.all(np.isfinite(A)) and np.all(np.isfinite(B))):
        return None
    ca, cb = A.mean(axis=0), B.mean(axis=0)
    a, b = A - ca, B - cb
    var_a = float(np.sum(a ** 2)) / len(A)
    if not var_a > 0:
        return None
    U, S, Vt = np.linalg.svd(b.T @ a / len(A))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
    R = U @ D @ Vt
    s = float(np.trace(np.diag(S) @ D)) / var_a
    return s, R, cb - s * R @ ca


def similarity_align(A, B) -> tuple[np.ndarray, float]:
    """A (N, 3) moved onto B (N, 3) by :func:`similarity_fit`; returns (the moved A, its RMS
    distance to B).  Compares two reconstructions that are each defined only up to a similarity.

    NaN (and an infinite RMS) when A or B is not finite or A has no extent.
    """
    A, B = np.asarray(A, float).reshape(-1, 3), np.asarray(B, float).reshape(-1, 3)
    fit = similarity_fit(A, B)
    if fit is None:
        return np.full_like(B, np.nan), float("inf")
    s, R, t = fit
    moved = s * A @ R.T + t
    return moved, float(np.sqrt(np.mean(np.sum((moved - B) ** 2, axis=1))))
