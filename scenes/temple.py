"""The synthetic TEMPLE scene: a two-view pair in exactly the official homework format.

The official data (two photographs of the Middlebury temple model and hand-picked points)
cannot ship with the kit, so this module makes a look-alike with full ground truth:

- a small Greek temple (stepped base, two rows of three columns, entablature, gable roof)
  lying on its side and seen from a corner, with a seeded 3D stone texture, on a dark
  background, seen by two cameras;
- camera 2 swings about the temple mostly along image y, so disparities, like the official
  pair's, are a few pixels in x and up to a few tens of pixels in y, and the epipolar lines
  are within a few degrees of vertical;
- correspondences (``some_corresp``), the same with hard outliers mixed in
  (``some_corresp_noisy``) and points to match (``templeCoords``), all stored as uint16
  integer pixels like the official files.

Conventions: world coordinates are camera 1's (M1 = [I | 0]); M2 = [R | t] maps world to
camera 2; C = K @ M; a pixel is (x, y) = (column, row); F maps points of image 1 to lines of
image 2 (x2^T F x1 = 0).

Example
-------
>>> scene = make_temple_scene(seed=3, width=320, height=240)   # doctest: +SKIP
>>> write_temple(scene, "data/temple")                          # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
from PIL import Image
from scipy import ndimage
from scipy.spatial import cKDTree

from core.geometry import (
    IDENTITY_POSE,
    CameraPair,
    camera_center,
    depths,
    eightpoint_scale,
    epipolar_distances,
    essential_from_pose,
    fundamental_from_pose,
    project,
)
from core.validate import as_positive_scalar

from .cameras import intrinsics, projection, rotation_about
from .envelope import BORDER_MARGIN, POSE_SLACK, pair_outside_envelope
from .render import (
    Cylinder,
    SolidTexture,
    box,
    cast_rays,
    pixel_rays,
    render_gbuffer,
    shade,
    visible_from,
    wedge,
)

__all__ = ["TempleScene", "make_temple_scene", "temple_model", "write_temple"]

# The official pair's intrinsics, as fractions of a 640 x 480 image.
_REF_WIDTH, _REF_HEIGHT = 640, 480
_PP_FRACTION = (302.32 / 640, 246.87 / 480)
_FY_OVER_FX = 1525.9 / 1520.4

# Warm limestone, linear RGB.
_STONE = np.array([0.97, 0.745, 0.52])


@dataclass(frozen=True, eq=False)
class TempleScene:
    """A rendered two-view temple scene with its ground truth.

    Images and the "stored" point arrays are exactly what :func:`write_temple` writes; the
    rest is ground truth that never goes into the data folder.

    Attributes
    ----------
    im1, im2 : ndarray, shape (H, W, 3), uint8
        The two RGB views.
    K1, K2 : ndarray, shape (3, 3)
        Intrinsics.
    M1 : ndarray, shape (3, 4)
        [I | 0]: world coordinates are camera 1's.
    M2 : ndarray, shape (3, 4)
        True [R | t] of camera 2 (world to camera 2).
    X : ndarray, shape (N, 3)
        True 3D points of the ``some_corresp`` pairs.
    pts1_true, pts2_true : ndarray, shape (N, 2), float
        Their exact projections (x, y) in image 1 and image 2.
    pts1, pts2 : ndarray, shape (N, 2), uint16
        Stored correspondences: exact projections plus Gaussian noise, rounded.
    pts1_noisy, pts2_noisy : ndarray, shape (N + N_out, 2), uint16
        ``pts1, pts2`` and N_out wrong pairs, shuffled together.
    inlier_mask : ndarray, shape (N + N_out,), bool
        True for the rows of ``*_noisy`` that are correct pairs.
    noisy_source : ndarray, shape (N + N_out,), int
        For an inlier row, its row in ``pts1, pts2``; -1 for an outlier.
    outlier_kind : ndarray, shape (N + N_out,), str
        "" for inliers, "epipolar" for an outlier slid along the true epipolar line,
        "random" for a wrong match elsewhere on the object.
    pts2_noisy_true : ndarray, shape (N + N_out, 2), float
        Where the true match of each row's image-1 point lies in image 2.
    x1, y1 : ndarray, shape (P, 1), uint16
        ``templeCoords``: pixels of image 1 on the temple.
    X_coords : ndarray, shape (P, 3)
        The 3D points seen at (x1, y1).
    x2_true : ndarray, shape (P, 2), float
        Their exact positions in image 2.
    visible2 : ndarray, shape (P,), bool
        Unoccluded and inside image 2.
    primitives : tuple of ConvexPolyhedron and Cylinder
        The temple's solids in world coordinates, to test visibility
        (``render.visible_from``) or to cast rays.
    seed : int
        The seed the scene was made from.

    All arrays are read-only.  Derived: ``width``, ``height``, ``M`` (= max(width, height),
    the homework's scale), ``C1``, ``C2``, ``R``, ``t``, ``E_true``, ``F_true`` (from core.geometry)
    and ``pair`` (a core.geometry.CameraPair of the cameras and ``X``).
    """

    im1: np.ndarray
    im2: np.ndarray
    K1: np.ndarray
    K2: np.ndarray
    M1: np.ndarray
    M2: np.ndarray
    X: np.ndarray
    pts1_true: np.ndarray
    pts2_true: np.ndarray
    pts1: np.ndarray
    pts2: np.ndarray
    pts1_noisy: np.ndarray
    pts2_noisy: np.ndarray
    inlier_mask: np.ndarray
    noisy_source: np.ndarray
    outlier_kind: np.ndarray
    pts2_noisy_true: np.ndarray
    x1: np.ndarray
    y1: np.ndarray
    X_coords: np.ndarray
    x2_true: np.ndarray
    visible2: np.ndarray
    primitives: tuple
    seed: int

    def __post_init__(self):
        # Scenes are cached and shared (scenes.defaults), so their arrays are read-only.
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.ndarray):
                value.flags.writeable = False

    @property
    def width(self) -> int:
        return self.im1.shape[1]

    @property
    def height(self) -> int:
        return self.im1.shape[0]

    @property
    def C1(self) -> np.ndarray:
        """Projection matrix K1 @ M1 (3x4)."""
        return projection(self.K1, self.M1)

    @property
    def C2(self) -> np.ndarray:
        """Projection matrix K2 @ M2 (3x4)."""
        return projection(self.K2, self.M2)

    @property
    def R(self) -> np.ndarray:
        """Rotation (3x3) of camera 2 relative to camera 1."""
        return self.M2[:, :3]

    @property
    def t(self) -> np.ndarray:
        """Translation (3,) of camera 2 relative to camera 1 (in the scene's units)."""
        return self.M2[:, 3]

    @property
    def pair(self) -> CameraPair:
        """The two cameras and the true points ``X`` of ``some_corresp`` as a core.geometry.CameraPair."""
        return CameraPair(self.K1, self.K2, self.M2, self.X)

    @property
    def E_true(self) -> np.ndarray:
        """Essential matrix [t]_x R (3x3), at the scale of the true t: x2n^T E x1n = 0."""
        return essential_from_pose(self.M2)

    @property
    def F_true(self) -> np.ndarray:
        """Fundamental matrix K2^-T E K1^-1 (3x3), scaled to unit Frobenius norm."""
        return fundamental_from_pose(self.K1, self.K2, self.M2)

    @property
    def M(self) -> float:
        """The homework's scale parameter: max(width, height) (``core.geometry.eightpoint_scale``)."""
        return eightpoint_scale(self.width, self.height)


# ----------------------------------------------------------------------------- geometry

def temple_model() -> list:
    """The temple's solids in its own frame.

    Frame: x across the facade, y from front (-y) to back, z up; the base sits on z = 0.
    Overall about 1.4 wide, 0.9 deep and 2.1 tall (scene units).

    Returns
    -------
    list of ConvexPolyhedron and Cylinder
    """
    prims = []
    # Three steps (the crepidoma).
    for k, (hx, hy) in enumerate([(0.70, 0.46), (0.65, 0.41), (0.60, 0.36)]):
        prims.append(box([0, 0, 0.06 + 0.12 * k], [hx, hy, 0.06]))
    # Two rows of three columns: seen obliquely, the rows give the scene real depth relief,
    # which the eight-point algorithm needs (a nearly planar scene makes F ill-conditioned).
    z0, z1 = 0.36, 1.52
    for x in (-0.42, 0.0, 0.42):
        for y in (-0.25, 0.25):
            prims.append(Cylinder([x, y, (z0 + z1) / 2], [0, 0, 1], 0.09, (z1 - z0) / 2))
            prims.append(Cylinder([x, y, z0 + 0.025], [0, 0, 1], 0.112, 0.025))  # column base
            prims.append(Cylinder([x, y, z1 - 0.035], [0, 0, 1], 0.107, 0.035))  # echinus
            prims.append(box([x, y, z1 + 0.025], [0.12, 0.12, 0.025]))  # abacus
    prims.append(box([0, 0, z1 + 0.11], [0.58, 0.30, 0.06]))  # architrave
    prims.append(box([0, 0, z1 + 0.22], [0.62, 0.34, 0.05]))  # frieze
    prims.append(box([0, 0, z1 + 0.31], [0.67, 0.39, 0.04]))  # cornice
    prims.append(wedge([0, 0, z1 + 0.35], 0.67, 0.39, 0.26))  # gable roof, ridge front to back
    return prims


# Nominal pose, tuned on the official pair: the temple turned 45 degrees about its axis (seen
# from a corner, for depth relief), camera 2's swing pivot placed so that the mean y disparity
# is about -7 px, a roll that gives the x disparities their spread, and a slight pan (toe) of
# camera 2 so that it does not fixate the pivot exactly (see _poses).
_POSE = dict(turn_deg=45.0, tilt_deg=-6.0, pivot_offset=-0.13, roll_deg=-1.8, toe_deg=0.04)


def _poses(rng, jitter: float, baseline_deg: float, distance: float, toe_deg: float = _POSE["toe_deg"]):
    """Object placement (R_obj (3, 3), t_obj (3,)) in camera-1 coordinates, and camera 2's
    M2 (3x4).  ``jitter`` scales the seeded perturbations: a few degrees of the temple's
    turn and tilt, about 1 % of its position, 8 % of the swing angle, 2 degrees of the swing
    axis, 0.3 degrees of camera 2's roll, and camera 2's toe between half and 1.5 times its
    nominal size, of either sign (never zero, see below)."""
    n = rng.standard_normal(12) * jitter
    # Temple up (object z) to image left (-x), facade across image y, depth away from camera 1;
    # then turned about its own axis and tilted so that its depth shows.
    base = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    turn = rotation_about([0, 0, 1], np.deg2rad(_POSE["turn_deg"] + 4 * n[0]))
    tilt = rotation_about([1, 0, 0], np.deg2rad(_POSE["tilt_deg"] + 3 * n[1]))
    R_obj = rotation_about([0, 0, 1], np.deg2rad(1.5 * n[2])) @ base @ tilt @ turn
    centre_obj = np.array([0.0, 0.0, 1.05])  # middle of the temple in its own frame
    target = distance * (np.array([-0.01, 0.0, 1.0]) + 0.008 * n[3:6])
    t_obj = target - R_obj @ centre_obj
    # Camera 2 swings about an axis through the temple, nearly parallel to camera 1's x axis,
    # so it moves mostly along image y; a slight roll adds the x disparities of the real pair.
    swing_axis = rotation_about([0, 0, 1], np.deg2rad(2.0 * n[6])) @ [1.0, 0, 0]
    angle = np.deg2rad(baseline_deg * (1 + 0.08 * n[7]))
    pivot = np.array([0.0, 0.0, target[2] + _POSE["pivot_offset"] + 0.03 * n[8]])
    Q = rotation_about(swing_axis, angle)  # camera 2's rig is camera 1's rotated by Q about the pivot
    roll = rotation_about([0, 0, 1], np.deg2rad(_POSE["roll_deg"] + 0.3 * n[9]))
    # Why a toe: the swing axis is perpendicular to camera 1's optical axis, so the swing keeps
    # both optical axes in one plane wherever the pivot is; they meet, and E[2, 2] (x2 = x1 = the
    # principal point) is exactly 0, which no real capture gives (the official pair: E33/|E| about
    # -2.8e-4) and which turns a student's E / E[2, 2] into inf or NaN.  Panning camera 2 about its
    # own y axis tilts its axis out of that plane: |E33|/|E| is about toe (radians) / sqrt(2).  The
    # seeded part scales the size (tanh keeps it within 0.5 to 1.5 times nominal, so it never
    # crosses zero) and picks the sign.
    toe = toe_deg * (1.0 + 0.5 * np.tanh(n[10])) * (-1.0 if n[11] < 0 else 1.0)
    R2 = rotation_about([0, 1, 0], np.deg2rad(toe)) @ roll @ Q.T
    c2 = pivot - Q @ pivot
    M2 = np.hstack([R2, (-R2 @ c2)[:, None]])
    return R_obj, t_obj, M2


# ----------------------------------------------------------------------------- appearance

def _stone_albedo(rng: np.random.Generator):
    """A seeded albedo function: world points (N, 3) -> warm stone RGB (N, 3)."""
    # Grain features of about 1-6 px at the default scale (1 px is about 0.005 units), what
    # 15x15 window matching needs; the blotches are the stone's slow variations.
    grain = SolidTexture(rng, cell=0.006, size=96, scales=(0.6, 1.2, 2.5), weights=(0.7, 0.8, 0.8))
    blotch = SolidTexture(rng, cell=0.045, size=48, scales=(0.8, 2.0), weights=(0.6, 1.0))
    tint = rng.normal(0.0, 0.02, 3)

    def albedo(X):
        b = blotch(X)
        g = grain(X)
        v = 0.6 * g + 0.5 * b
        # The grain's rare peaks become dark pits and chips, like the real model's plaster.
        pit = np.clip((g - 2.0) / 0.5, 0.0, 1.0)
        lum = np.clip(0.84 + 0.12 * v, 0.35, 1.1) * (1.0 - 0.5 * pit)
        # Slight hue drift between ochre and grey across the stone.
        hue = (_STONE + tint) * (1.0 + 0.03 * b[:, None] * np.array([1.0, 0.3, -0.6]))
        return hue * lum[:, None]

    return albedo


def _backdrop(K, M, width: int, height: int, cloth: SolidTexture) -> np.ndarray:
    """A dark, softly varying backdrop (H, W, 3) in [0, 1], far away: a function of the
    viewing direction only, so both views see the same backdrop, each through its own
    rotation."""
    step = 8
    gx, gy = np.meshgrid(np.arange(0, width + step, step, dtype=float),
                         np.arange(0, height + step, step, dtype=float))
    _, d = pixel_rays(K, M, np.stack([gx.ravel(), gy.ravel()], axis=1))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    v = cloth(d * 8.0).reshape(gx.shape)
    level = 0.01 + 0.09 * np.clip(0.5 + 0.35 * v, 0.0, 1.0) ** 2  # 2.5 to 25 grey levels
    full = ndimage.zoom(level, step, order=1)[:height, :width]
    return full[..., None] * np.array([1.0, 0.95, 0.85])


# ----------------------------------------------------------------------------- points

def _spread(xy: np.ndarray, n: int, rng: np.random.Generator, spacing: float) -> np.ndarray:
    """Indices of up to n rows of xy (N, 2), spread out like hand-picked points.

    Hard-core thinning: candidates get a random rank, and of every pair closer than a
    radius the later-ranked one is dropped; the radius starts at ``spacing`` and shrinks
    until at least n survive, and the n best-ranked survivors are returned.
    """
    if n <= 0 or len(xy) == 0:
        return np.zeros(0, dtype=np.intp)
    # Candidates are in random positions already; more than ~8 per point only costs time.
    pool = rng.permutation(len(xy))[:8 * n]
    tree = cKDTree(xy[pool])
    radius = spacing
    while True:
        pairs = tree.query_pairs(radius, output_type="ndarray")
        keep = np.ones(len(pool), bool)
        keep[pairs.max(axis=1)] = False  # pool order is the rank: the later one goes
        if keep.sum() >= n or radius < 0.5:
            return pool[np.flatnonzero(keep)[:n]]
        radius *= 0.85


def _inside(xy: np.ndarray, width: int, height: int, margin: float) -> np.ndarray:
    return ((xy[:, 0] >= margin) & (xy[:, 0] <= width - 1 - margin)
            & (xy[:, 1] >= margin) & (xy[:, 1] <= height - 1 - margin))


def _facing(normal: np.ndarray, X: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Cosine (N,) between each surface normal and the direction to a camera centre."""
    v = centre - X
    return np.einsum("ij,ij->i", normal, v) / np.linalg.norm(v, axis=1)


def _to_uint16(xy: np.ndarray) -> np.ndarray:
    return np.rint(xy).astype(np.uint16)


# ----------------------------------------------------------------------------- the scene

_MARGIN = 10  # pixels kept clear of every image border, so a 15x15 window always fits
_DISTANCE = 7.6  # camera 1 to the temple, in scene units
_MIN_SIZE = 96
_POSE_TRIES = 20


def _check_int(value, name: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {value!r}")
    return int(value)


def _check_range(value, name: str, lo: float, hi: float) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number in [{lo}, {hi}], got {value!r}") from None
    if not (lo <= v <= hi):
        raise ValueError(f"{name}: expected a number in [{lo}, {hi}], got {value!r}")
    return v


def make_temple_scene(seed: int = 0, *, width: int = 640, height: int = 480, n_corresp: int = 110,
                      n_outliers: int = 30, n_coords: int = 288, noise_px: float = 0.2,
                      baseline_deg: float = 11.0, focal: float | None = None, jitter: float = 1.0,
                      epipolar_outliers: float = 0.5, image_noise: float = 1.2,
                      exposure2: float = 0.96, supersample: int = 2,
                      coords_margin: int = BORDER_MARGIN, toe_deg: float | None = None) -> TempleScene:
    """Render a two-view temple scene and pick its correspondences, with ground truth.

    The defaults give data like the official set: 640x480 images, focal length about 1520 px,
    110 + 30 correspondences and 288 points to match, disparities of a few pixels in x and
    a few tens in y.  The result depends only on the arguments (bit-identical arrays for the
    same arguments on the same machine).

    Parameters
    ----------
    seed : int
        Seeds every random choice: the pose jitter, the stone texture, the light, the image
        noise and the points.
    width, height : int
        Image size in pixels (at least 96 each).
    n_corresp : int
        Number of correct pairs in ``some_corresp`` (at least 8).
    n_outliers : int
        Number of wrong pairs added to make ``some_corresp_noisy``.
    n_coords : int
        Number of ``templeCoords`` points.
    noise_px : float
        Standard deviation (pixels) of the Gaussian noise added to the exact projections
        before they are rounded to integer pixels.
    baseline_deg : float
        How far (degrees) camera 2 swings about the temple relative to camera 1.
    focal : float, optional
        Focal length in pixels; by default 1520 scaled by min(width / 640, height / 480),
        so the temple fills the same share of any image.  The principal point is always at
        the official pair's fraction of the image, about (0.47 W, 0.51 H).
    jitter : float
        Scale of the seeded random perturbations of the temple's pose, the swing and the
        light (0 gives the nominal configuration for every seed).
    epipolar_outliers : float
        Fraction of the outliers that slide 8-40 px along the true epipolar line (so they pass
        an epipolar test); the others are wrong matches elsewhere on the temple, at least
        6 px off the line.
    image_noise : float
        Standard deviation of the sensor noise, in grey levels.
    exposure2 : float
        Brightness of view 2 relative to view 1 (the official im2 is slightly darker).
    supersample : int
        Anti-aliasing: samples per pixel along each axis at edges.
    coords_margin : int
        Pixels every templeCoords point and its true match in view 2 keep from every border
        (default scenes.envelope.BORDER_MARGIN: a 101 px window fits without padding); at
        least 10.  Smaller images than the envelope's need a smaller value.
    toe_deg : float, optional
        Nominal pan (degrees) of camera 2 about its own y axis (None: 0.04, the official pair's
        E33).  It shifts image 2 sideways by about focal * toe, which parts the epipolar line
        F x1 from its transpose's F^T x1 by twice that at the match (a matcher searching the
        wrong one then misses); seeded between half and 1.5 times it, of either sign.

    Returns
    -------
    TempleScene
    """
    seed = _check_int(seed, "seed", 0)
    width = _check_int(width, "width", _MIN_SIZE)
    height = _check_int(height, "height", _MIN_SIZE)
    n_corresp = _check_int(n_corresp, "n_corresp", 8)
    n_outliers = _check_int(n_outliers, "n_outliers", 0)
    n_coords = _check_int(n_coords, "n_coords", 1)
    noise_px = _check_range(noise_px, "noise_px", 0.0, 5.0)
    baseline_deg = _check_range(baseline_deg, "baseline_deg", 0.5, 30.0)
    toe_deg = _POSE["toe_deg"] if toe_deg is None else _check_range(toe_deg, "toe_deg", 0.01, 1.0)
    jitter = _check_range(jitter, "jitter", 0.0, 3.0)
    epipolar_outliers = _check_range(epipolar_outliers, "epipolar_outliers", 0.0, 1.0)
    image_noise = _check_range(image_noise, "image_noise", 0.0, 50.0)
    exposure2 = _check_range(exposure2, "exposure2", 0.25, 4.0)
    supersample = _check_int(supersample, "supersample", 1)
    coords_margin = _check_int(coords_margin, "coords_margin", _MARGIN)
    scale = min(width / _REF_WIDTH, height / _REF_HEIGHT)
    f = 1520.0 * scale if focal is None else as_positive_scalar(focal, "focal")

    # Independent streams, so that asking for more points leaves the images unchanged.
    geo_rng, look_rng, img_rng, pts_rng = np.random.default_rng(seed).spawn(4)
    K = intrinsics(f, _PP_FRACTION[0] * width, _PP_FRACTION[1] * height, f * _FY_OVER_FX)
    M1 = IDENTITY_POSE.copy()
    # A seeded pose whose E or F has a last entry near zero (scenes.envelope) is drawn again from
    # the same stream: a student's E / E[2, 2] or F / F[2, 2] must stay well conditioned.
    for _ in range(_POSE_TRIES):
        R_obj, t_obj, M2 = _poses(geo_rng, jitter, baseline_deg, _DISTANCE, toe_deg)
        outside = pair_outside_envelope(K, K, M2, slack=POSE_SLACK)
        if not outside:
            break
    else:
        raise ValueError(f"baseline_deg, jitter: no pose inside the envelope in {_POSE_TRIES} draws ({outside[0]})")
    prims = [p.transformed(R_obj, t_obj) for p in temple_model()]

    albedo = _stone_albedo(look_rng)
    cloth = SolidTexture(look_rng, cell=0.25, size=32, scales=(1.0, 2.5), weights=(0.5, 1.0))
    light = np.array([-0.4, -0.3, -1.0]) + 0.15 * jitter * look_rng.standard_normal(3)
    light *= 0.7 / np.linalg.norm(light)
    views = []
    for M, gain in ((M1, 1.0), (M2, exposure2)):
        g = render_gbuffer(prims, K, M, width, height, supersample)
        im = shade(g, albedo, light=light, ambient=0.45, gain=gain, noise_sigma=image_noise,
                   background=_backdrop(K, M, width, height, cloth), rng=img_rng)
        views.append((g, im))
    (g1, im1), (g2, im2) = views

    scene_args = dict(K=K, M1=M1, M2=M2, prims=prims, g1=g1, g2=g2, width=width, height=height)
    clean, outliers = _correspondences(pts_rng, n_corresp, n_outliers, noise_px, epipolar_outliers,
                                       **scene_args)
    coords = _temple_coords(pts_rng, n_coords, coords_margin, **scene_args)

    n_all = n_corresp + n_outliers
    order = pts_rng.permutation(n_all)
    source = np.concatenate([np.arange(n_corresp), np.full(n_outliers, -1)])[order]
    kind = np.concatenate([np.full(n_corresp, ""), outliers["kind"]]).astype("<U8")[order]
    return TempleScene(
        im1=im1, im2=im2, K1=K.copy(), K2=K.copy(), M1=M1, M2=M2,
        X=clean["X"], pts1_true=clean["x1"], pts2_true=clean["x2"],
        pts1=clean["p1"], pts2=clean["p2"],
        pts1_noisy=np.concatenate([clean["p1"], outliers["p1"]])[order],
        pts2_noisy=np.concatenate([clean["p2"], outliers["p2"]])[order],
        inlier_mask=source >= 0, noisy_source=source, outlier_kind=kind,
        pts2_noisy_true=np.concatenate([clean["x2"], outliers["x2"]])[order],
        x1=coords["x1"], y1=coords["y1"], X_coords=coords["X"], x2_true=coords["x2"],
        visible2=coords["visible2"], primitives=tuple(prims), seed=seed,
    )


def _surface_points(K, M1, M2, prims, xy1):
    """Cast camera-1 rays through xy1 (N, 2); return the hit points X (N, 3), their
    projections x2 (N, 2) in view 2, and whether each is hit, unoccluded in view 2 and seen
    at least obliquely enough (cosine 0.25) by both cameras."""
    o, d = pixel_rays(K, M1, xy1)
    hits = cast_rays(prims, o, d)
    ok = np.isfinite(hits.t)
    X = o + np.where(ok, hits.t, 1.0)[:, None] * d
    x2 = project(projection(K, M2), X)
    ok &= _facing(hits.normal, X, camera_center(M1)) >= 0.25
    ok &= _facing(hits.normal, X, camera_center(M2)) >= 0.25
    ok &= depths(M2, X) > 0
    ok[ok] &= visible_from(prims, M2, X[ok])
    return X, x2, ok


def _correspondences(rng, n_corresp, n_outliers, noise_px, epipolar_fraction, *, K, M1, M2,
                     prims, g1, g2, width, height):
    """The clean pairs and the outliers (dicts of arrays), see make_temple_scene."""
    full1 = (g1.coverage >= 1) & (g1.prim >= 0)
    ys, xs = np.nonzero(full1)
    n_try = min(len(xs), 40 * (n_corresp + n_outliers))
    pick = rng.choice(len(xs), size=n_try, replace=False)
    xy1 = np.stack([xs[pick], ys[pick]], axis=1) + rng.uniform(-0.5, 0.5, (n_try, 2))
    X, x2, ok = _surface_points(K, M1, M2, prims, xy1)
    # Two extra pixels of margin leave room for the rounding noise of the stored points.
    ok &= _inside(xy1, width, height, _MARGIN + 2) & _inside(x2, width, height, _MARGIN + 2)
    good = np.flatnonzero(ok)
    spacing = 0.8 * np.sqrt(len(xs) / max(n_corresp, 1))
    chosen = good[_spread(xy1[good], n_corresp, rng, spacing)]
    if len(chosen) < n_corresp:
        raise ValueError(f"n_corresp: only {len(chosen)} usable temple points found for the "
                         f"{n_corresp} asked; use fewer points or a larger image")

    def store(xy):
        noisy = xy + rng.normal(0.0, noise_px, xy.shape) if noise_px > 0 else xy
        lo, hi = _MARGIN, np.array([width, height]) - 1 - _MARGIN
        return _to_uint16(np.clip(noisy, lo, hi))

    clean = dict(X=X[chosen], x1=xy1[chosen], x2=x2[chosen], p1=store(xy1[chosen]), p2=store(x2[chosen]))

    rest = good[~np.isin(good, chosen)]
    far = np.min(np.linalg.norm(xy1[rest][:, None] - xy1[chosen][None], axis=2), axis=1) >= 4
    rest = rest[far]
    out_idx = rest[_spread(xy1[rest], n_outliers, rng, spacing)]
    if len(out_idx) < n_outliers:
        raise ValueError(f"n_outliers: only {len(out_idx)} usable temple points left for the "
                         f"{n_outliers} asked; use fewer points or a larger image")
    F = fundamental_from_pose(K, K, M2)
    full2 = (g2.coverage >= 1) & (g2.prim >= 0)
    full2[:_MARGIN] = full2[-_MARGIN:] = False
    full2[:, :_MARGIN] = full2[:, -_MARGIN:] = False
    on2 = np.stack(np.nonzero(full2)[::-1], axis=1).astype(float)  # (x, y) of object pixels in view 2
    n_epi = round(epipolar_fraction * n_outliers)
    p1 = store(xy1[out_idx])
    p2 = np.zeros((n_outliers, 2), np.uint16)
    kinds = []
    for j, i in enumerate(out_idx):
        q, kind = None, "random"
        if j < n_epi:
            q = _slide_along_line(rng, F, p1[j].astype(float), x2[i], full2, width, height)
            kind = "epipolar"
        if q is None:
            q, kind = _wrong_match(rng, F, p1[j].astype(float), x2[i], on2), "random"
        p2[j] = q
        kinds.append(kind)
    outliers = dict(x1=xy1[out_idx], x2=x2[out_idx], p1=p1, p2=p2, kind=np.array(kinds, dtype="<U8"))
    return clean, outliers


def _slide_along_line(rng, F, p1, x2_true, on_object2, width, height):
    """An integer pixel 8-40 px from the true match along the epipolar line of p1 (within
    0.6 px of the line after rounding), on the temple in view 2 when possible; None if no
    such pixel fits in the image."""
    a, b, c = F @ np.array([p1[0], p1[1], 1.0])
    n = np.hypot(a, b)
    a, b, c = a / n, b / n, c / n
    foot = x2_true - (a * x2_true[0] + b * x2_true[1] + c) * np.array([a, b])
    along = np.array([-b, a])
    fallback = None
    for _ in range(60):
        q = np.rint(foot + rng.choice([-1.0, 1.0]) * rng.uniform(8.0, 40.0) * along)
        if not _inside(q[None], width, height, _MARGIN)[0]:
            continue
        if abs(a * q[0] + b * q[1] + c) > 0.6 or np.linalg.norm(q - x2_true) < 6.0:
            continue
        if on_object2[int(q[1]), int(q[0])]:
            return q
        fallback = q if fallback is None else fallback
    return fallback


def _wrong_match(rng, F, p1, x2_true, on2):
    """A random pixel of the temple in view 2 at least 6 px from p1's epipolar line and
    from the true match."""
    for _ in range(200):
        q = on2[rng.integers(len(on2))]
        if (epipolar_distances(F, p1[None], q[None])[0] >= 6.0
                and np.linalg.norm(q - x2_true) >= 6.0):
            return q
    raise ValueError("n_outliers: could not place a wrong match away from the epipolar line")


# templeCoords placement, in pixels of a 640-wide image: the outline band's distance from the
# silhouette, the interior points' distance from it, and the least distance from an occluding
# edge inside the temple.  8 px keeps a 15x15 window on one surface in view 1.
_COORDS = dict(band=(8.0, 11.0), interior=12.0, edge_gap=8.0, facing=0.3, outline_share=0.55)


def _occluding_edges(g) -> np.ndarray:
    """Pixels (H, W) bool next to a silhouette or a depth jump of more than 1 %."""
    depth = np.where(np.isfinite(g.depth), g.depth, 1e9)
    edge = np.zeros(depth.shape, bool)
    for axis in (0, 1):
        a = np.take(depth, np.arange(depth.shape[axis] - 1), axis=axis)
        b = np.take(depth, np.arange(1, depth.shape[axis]), axis=axis)
        jump = np.abs(a - b) > 0.01 * np.minimum(a, b)
        lo = [slice(None)] * 2
        hi = [slice(None)] * 2
        lo[axis], hi[axis] = slice(0, -1), slice(1, None)
        edge[tuple(lo)] |= jump
        edge[tuple(hi)] |= jump
    return edge


def _temple_coords(rng, n_coords, margin, *, K, M1, M2, prims, g1, g2, width, height):
    """templeCoords: integer pixels of view 1 on the temple, about half in a band just inside
    its outline (like the official hand-traced points) and the rest spread over its faces,
    all at least a window's half-width from any occluding edge of view 1, and each point and
    its true match in view 2 at least ``margin`` px from every border."""
    px = min(width / _REF_WIDTH, height / _REF_HEIGHT)
    band = [max(3.0, v * px) for v in _COORDS["band"]]
    full1 = (g1.coverage >= 1) & (g1.prim >= 0)
    inset = ndimage.distance_transform_edt(full1)
    gap = ndimage.distance_transform_edt(~_occluding_edges(g1))
    inner = full1 & (gap >= max(3.0, _COORDS["edge_gap"] * px))
    n_outline = round(_COORDS["outline_share"] * n_coords)
    in_band = (inset >= band[0]) & (inset <= band[1])
    in_area = inset >= max(band[1] + 1, _COORDS["interior"] * px)
    # (mask, how many, spread along a band or over an area); the last group, with looser
    # rules, only tops up what the first two could not place (small images).
    groups = [(in_band & inner, lambda got: n_outline, "band"),
              (in_area & inner, lambda got: n_coords - got, "area"),
              (full1 & (inset >= 2) & (gap >= 2), lambda got: n_coords - got, "area")]
    inner_frame = np.zeros_like(full1)
    inner_frame[margin:-margin, margin:-margin] = True
    picked = np.zeros((0, 2))
    for mask, want, shape in groups:
        n = want(len(picked))
        ys, xs = np.nonzero(mask & inner_frame)
        if n <= 0 or len(xs) == 0:
            continue
        take = rng.choice(len(xs), size=min(len(xs), 30 * n), replace=False)
        xy = np.stack([xs[take], ys[take]], axis=1).astype(float)
        if len(picked):
            xy = xy[cKDTree(picked).query(xy)[0] >= 2.0]
        o, d = pixel_rays(K, M1, xy)
        hits = cast_rays(prims, o, d)
        ok = np.isfinite(hits.t)
        ok[ok] &= _facing(hits.normal[ok], o + hits.t[ok, None] * d[ok], o) >= _COORDS["facing"]
        # The true match must leave the same room in view 2: a matcher cuts its window there too.
        ok[ok] &= _inside(project(projection(K, M2), o + hits.t[ok, None] * d[ok]), width, height, margin)
        xy = xy[ok]
        # Spacing for n points along a band, or over an area.
        spacing = len(xs) / (band[1] - band[0] + 1) / n if shape == "band" else np.sqrt(len(xs) / n)
        picked = np.concatenate([picked, xy[_spread(xy, n, rng, 0.9 * spacing)]])
    xy1 = picked
    if len(xy1) < n_coords:
        raise ValueError(f"n_coords: only {len(xy1)} temple pixels found at least {margin} px from the "
                         f"borders for the {n_coords} asked; use fewer points, a larger image or a "
                         "smaller coords_margin")
    o, d = pixel_rays(K, M1, xy1)
    X = o + cast_rays(prims, o, d).t[:, None] * d
    x2 = project(projection(K, M2), X)
    visible2 = visible_from(prims, M2, X) & _inside(x2, width, height, 0)
    p = _to_uint16(xy1)
    return dict(x1=p[:, :1].copy(), y1=p[:, 1:].copy(), X=X, x2=x2, visible2=visible2)


# ----------------------------------------------------------------------------- files

def write_temple(scene: TempleScene, folder) -> None:
    """Write a scene in exactly the official layout, and nothing else.

    Files: im1.png, im2.png (8-bit RGB), intrinsics.npz (K1, K2: float64 3x3),
    some_corresp.npz (pts1, pts2: uint16 (N, 2)), some_corresp_noisy.npz (pts1, pts2:
    uint16 (N + N_out, 2)), templeCoords.npz (x1, y1: uint16 (P, 1)).  The ground truth
    stays in the TempleScene.  The folder is created if needed; existing files of these
    names are replaced.  The bytes depend only on the scene (np.savez stamps a fixed date).
    """
    if not isinstance(scene, TempleScene):
        raise ValueError(f"scene: expected a TempleScene, got {type(scene).__name__}")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name, im in (("im1.png", scene.im1), ("im2.png", scene.im2)):
        # No metadata, fixed compression: the same image always gives the same bytes.
        Image.fromarray(np.ascontiguousarray(im, dtype=np.uint8)).save(
            folder / name, format="PNG", optimize=False, compress_level=6)
    u16 = lambda a: np.ascontiguousarray(a, dtype=np.uint16)
    np.savez(folder / "intrinsics.npz", K1=np.asarray(scene.K1, np.float64), K2=np.asarray(scene.K2, np.float64))
    np.savez(folder / "some_corresp.npz", pts1=u16(scene.pts1), pts2=u16(scene.pts2))
    np.savez(folder / "some_corresp_noisy.npz", pts1=u16(scene.pts1_noisy), pts2=u16(scene.pts2_noisy))
    np.savez(folder / "templeCoords.npz", x1=u16(scene.x1), y1=u16(scene.y1))
