"""The data the public checks run on: generated scenes with known answers, and the default data.

Generated data comes from the kit's scene generator with a fixed, public seed, made once per
session (about a second).  The two-view data reuse the generated temple's 3D points and
cameras at the official scale (640 x 480, M = 640, products of coordinates above 65535), with
a camera 2 whose intrinsics differ from camera 1's, so that K1 and K2 cannot be confused
unnoticed.  The default data is whatever ``starter.load_temple`` / ``load_car_frame`` find; it
has no ground truth, so the checks compare with an independent estimate made with OpenCV when
it is installed.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from core.geometry import IDENTITY_POSE, CameraPair
from judging.triangulation import reprojection_error

__all__ = [
    "PUBLIC_SEED",
    "NoisyPair",
    "OpenCVReference",
    "car_frame",
    "default_car",
    "default_temple",
    "linear_triangulation_error",
    "noisy_pair",
    "opencv_reference",
    "temple_scene",
    "two_view",
]

PUBLIC_SEED = 720
_NOISE_PX = 0.5


@dataclass(frozen=True, eq=False)
class NoisyPair:
    """A camera pair with known answers and the noisy matches a check needs.

    pair : core.geometry.CameraPair (K1, K2, M2, X and every derived truth: C1, C2, pts1, pts2, E, F).
    pts1_u16, pts2_u16 : (N, 2) uint16, the projections plus noise, rounded (the data files' form).
    M : the scale parameter, max(width, height).
    """

    pair: CameraPair
    pts1_u16: np.ndarray
    pts2_u16: np.ndarray
    M: float


def noisy_pair(scene) -> NoisyPair:
    """The NoisyPair of a TempleScene (its cameras, true points and stored uint16 matches)."""
    return NoisyPair(scene.pair, np.asarray(scene.pts1), np.asarray(scene.pts2), float(scene.M))


@lru_cache(maxsize=1)
def temple_scene():
    """The generated temple pair (320 x 240, rendered) the image checks use; made once."""
    from scenes.temple import make_temple_scene

    return make_temple_scene(PUBLIC_SEED, width=320, height=240, n_corresp=60, n_outliers=0,
                             n_coords=60, supersample=1)


@lru_cache(maxsize=1)
def two_view() -> NoisyPair:
    """The generated temple's geometry seen by 640 x 480 cameras with K1 != K2 (see module doc)."""
    s = temple_scene()
    K1 = np.diag([2.0, 2.0, 1.0]) @ s.K1
    K2 = K1.copy()
    K2[0, 0] *= 1.04
    K2[1, 1] *= 1.04
    K2[:2, 2] += [7.0, -5.0]
    pair = CameraPair(K1, K2, s.M2.copy(), s.X.copy())
    rng = np.random.default_rng(PUBLIC_SEED)

    def stored(p):
        return np.rint(p + rng.normal(0.0, _NOISE_PX, p.shape)).astype(np.uint16)

    return NoisyPair(pair, stored(pair.pts1), stored(pair.pts2), 640.0)


@lru_cache(maxsize=1)
def car_frame():
    """(C (3, 3, 4), P_true (12, 3)) of one generated time step of the car scene (no images)."""
    from scenes.car import make_car_scene

    scene = make_car_scene(PUBLIC_SEED, n_times=1, render=False)
    return scene.C[0].copy(), scene.P_true[0].copy()


def default_temple(root=None):
    """(TempleData or None, note): the default temple data, or why there is none."""
    from starter.data import load_temple

    try:
        return load_temple(root), ""
    except FileNotFoundError:
        return None, "no temple data found in data/ (or $HW4_DATA): checked on generated scenes only"
    except ValueError as exc:
        return None, f"the temple data could not be read ({exc}): checked on generated scenes only"


def default_car(root=None):
    """(CarFrame of the first time step or None, note)."""
    from starter.data import car_times, load_car_frame

    try:
        return load_car_frame(car_times(root)[0], root, images=False), ""
    except FileNotFoundError:
        return None, "no car data found in data/q6: checked on a generated scene only"
    except ValueError as exc:
        return None, f"the car data could not be read ({exc}): checked on a generated scene only"


@dataclass(frozen=True, eq=False)
class OpenCVReference:
    """An independent two-view estimate on the default data (no ground truth there).

    F : (3, 3) pixels, 8-point on the clean matches.  M2 : (3, 4), |t| = 1, the pose OpenCV
    recovers from this F.  C1, C2 : (3, 4).  w : (N, 3) the matches triangulated with C1, C2 (linear).
    err : their total squared reprojection error.
    """

    F: np.ndarray
    M2: np.ndarray
    C1: np.ndarray
    C2: np.ndarray
    w: np.ndarray
    err: float


_REFERENCES: dict = {}


def opencv_reference(data):
    """(OpenCVReference or None, note) for a TempleData; None when OpenCV is not installed."""
    try:
        import cv2
    except ImportError:
        return None, "OpenCV (cv2) is not installed: the default data is only partly checked"
    key = str(data.folder)
    if key not in _REFERENCES:
        p1, p2 = np.ascontiguousarray(data.pts1, float), np.ascontiguousarray(data.pts2, float)
        F, _ = cv2.findFundamentalMat(p1, p2, cv2.FM_8POINT)
        # The pose of this very F, so that a findM2 given F can be compared with it; OpenCV
        # wants E and the points in normalised camera coordinates.
        n1 = cv2.undistortPoints(p1[:, None], data.K1, None)[:, 0]
        n2 = cv2.undistortPoints(p2[:, None], data.K2, None)[:, 0]
        _, R, t, _ = cv2.recoverPose(data.K2.T @ F @ data.K1, n1, n2, np.eye(3))
        M2 = np.hstack([R, t.reshape(3, 1) / np.linalg.norm(t)])
        C1, C2 = data.K1 @ IDENTITY_POSE, data.K2 @ M2
        X = cv2.triangulatePoints(C1, C2, p1.T, p2.T)
        w = (X[:3] / X[3]).T
        err = reprojection_error(C1, p1, C2, p2, w)
        _REFERENCES[key] = OpenCVReference(F / np.linalg.norm(F), M2, C1, C2, w, err)
    return _REFERENCES[key], ""


def linear_triangulation_error(C1, pts1, C2, pts2) -> float | None:
    """The total squared reprojection error (pixels^2) of OpenCV's linear triangulation of the
    matches (N, 2) with the cameras C1, C2 (3, 4); None when OpenCV is not installed."""
    try:
        import cv2
    except ImportError:
        return None
    p1, p2 = np.ascontiguousarray(pts1, float), np.ascontiguousarray(pts2, float)
    X = cv2.triangulatePoints(np.asarray(C1, float), np.asarray(C2, float), p1.T, p2.T)
    return reprojection_error(C1, p1, C2, p2, (X[:3] / X[3]).T)
