"""The catalogue of known mistakes: pure functions that recognise them in arrays.

Each function takes what a student's code returned (and what the caller knows to be true),
and returns a :class:`Mistake` (or a list of them) when the numbers carry the signature of a
known mistake, ``None`` (or ``[]``) otherwise.  Nothing here calls student code or prints, so
the public checks and the hidden tests share one catalogue (through judging/<concept>.py).

Conventions: a pixel is (x, y) = (column, row); F maps a point x1 of image 1 to the line
F x1 of image 2 (x2^T F x1 = 0); M = [R | t] (3x4) maps world to camera coordinates;
C = K M.  F and E are compared up to scale and sign.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np

from core.geometry import depths, skew, symmetric_epipolar_distances
from core.pose import camera2

__all__ = [
    "KNOWN_MISTAKES",
    "Mistake",
    "ba_mistakes",
    "error_not_sum_of_squares",
    "essential_mistakes",
    "fundamental_mistakes",
    "mistake",
    "one_camera_depth",
    "points_behind_cameras",
    "points_xy_swapped",
    "rank2_not_enforced",
    "residual_layout",
    "same_up_to_scale",
    "threshold_mistakes",
    "uint16_wraparound",
    "w_not_divided",
    "wrong_camera",
]


@dataclass(frozen=True)
class Mistake:
    """A recognised mistake.

    code : stable identifier (a key of ``KNOWN_MISTAKES``), for programs.
    name : short name for people, e.g. "F transposed".
    hint : one line saying what to do instead.
    evidence : the figures that gave it away (may be empty).
    """

    code: str
    name: str
    hint: str
    evidence: str = ""

    def __str__(self) -> str:
        return f"{self.name}: {self.hint}" + (f" ({self.evidence})" if self.evidence else "")


KNOWN_MISTAKES: dict[str, tuple[str, str]] = {
    # Each hint says what is wrong and where to look, not the fix; facts the handout gives as
    # given (the x2^T F x1 = 0 convention, T that scales the points, the residuals' layout, the
    # error's definition) may be named, never the answer it asks students to find.
    "f_transposed": (
        "F transposed",
        ("F must send a point of image 1 to its line in image 2 (x2^T F x1 = 0); yours is the transpose: "
         "look at the order of the image-1 and image-2 coordinates in each row of your system.")),
    "f_rank3": (
        "rank 2 not enforced",
        ("a fundamental matrix is singular (rank 2) and yours has full rank: look at the step the handout "
         "asks for before unscaling (the singularity condition); refineF may hide that it is missing.")),
    "f_not_unscaled": (
        "F not unscaled",
        ("your F fits the points divided by M, not the pixels: the unscaling step the handout's hint "
         "describes is missing.")),
    "f_unscaled_wrong_way": (
        "F unscaled the wrong way",
        ("you unscaled with the inverse of the matrix T that scaled the points (x_scaled = T x): "
         "look at which matrix your unscaling uses.")),
    "xy_swapped": (
        "x and y swapped",
        ("a pixel is (x, y) = (column, row): x indexes columns and y rows; look at the order of the "
         "coordinates you use and return.")),
    "uint16_wraparound": (
        "uint16 wrap-around",
        ("the data files hold uint16 points, where 54 - 55 is 65535 and products above 65535 wrap around: "
         "look at the dtype your arithmetic runs in.")),
    "e_k_order": (
        "K1 and K2 swapped in E",
        ("your E has the intrinsics of each camera where the other's belong: F takes points of image 1 "
         "(x2^T F x1 = 0), so look at which side of F each camera's intrinsics act on.")),
    "e_missing_k": (
        "a K missing in E",
        ("E relates normalised coordinates of both images, so both cameras' intrinsics enter it: "
         "look at which one your E leaves out.")),
    "e_inverse_k": (
        "inverse K in E",
        ("your E uses inverted intrinsics: look at which way your formula goes, from E to F or from F to E "
         "(pixels versus normalised coordinates).")),
    "e_same_k": (
        "the same K on both sides of E",
        ("your E uses one camera's intrinsics on both sides of F; each image has its own, and here "
         "they differ.")),
    "e_transposed": (
        "E transposed",
        ("your E is the transpose of the essential matrix: like F, it takes (normalised) points of image 1 "
         "to lines of image 2; look at the order of your factors.")),
    "w_not_divided": (
        "w not divided by its last coordinate",
        ("each row of w is a multiple of a right 3D point, by a factor that differs from point to point: "
         "look at where the homogeneous solution (4 numbers, defined up to scale) becomes the 3 coordinates "
         "of w.")),
    "error_not_sum_of_squares": (
        "error not the sum of squares",
        # Q3.2 and Q5 have two images, Q6 three views: the hint holds for any number of them.
        ("err is not the handout's total (squared distances in pixels^2, summed over every point in every "
         "image it is used in): compare your formula with the handout's.")),
    "points_behind": (
        "points behind a camera",
        ("most of your points have a negative depth in camera 1 or camera 2 (the third coordinate of "
         "M [w; 1]): look at how the camera, or the sign of the points, was chosen.")),
    "wrong_camera": (
        "wrong camera of the four",
        ("your M2 is another of camera2's four candidates: all four reproject the points equally well, "
         "so the reprojection error cannot tell them apart; look at what else differs between them.")),
    "depth_one_camera": (
        "depth tested in one camera only",
        ("your M2 puts every point in front of one camera and behind the other; on these matches that "
         "candidate also reprojects best, so the error cannot be what decides: look at which cameras your "
         "depth test looks at.")),
    "residual_layout": (
        "residuals in another layout",
        ("your residuals hold the right values in another order: compare your layout with the handout's "
         "(where image 1 and image 2 go, and the x and y of each point).")),
    "x_packing": (
        "x unpacked in another order",
        ("x is read in another order than the handout's flattened concatenation of w, r2 and t2: look at "
         "how you cut x into the points, r2 and t2, and the order of each point's coordinates.")),
    "ba_not_decreasing": (
        "BA error not decreasing",
        ("the returned M2 and w have no lower error than the start: look at what your code unpacks after "
         "the optimiser has run, and at the objective it is given.")),
    "ba_scale_collapse": (
        "BA scale collapse",
        ("points and t shrank together towards 0: any scale is right, but a vanishing one is no longer a "
         "reconstruction; look at what keeps your optimisation from shrinking the scene.")),
    "threshold_inclusive": (
        "detections at exactly Thres used",
        ("detections whose confidence equals Thres were used: look at the comparison that selects the "
         "detections (the handout keeps those above the threshold).")),
    "threshold_ignored": (
        "low-confidence detections used",
        ("detections whose confidence is below Thres were used: look at where your code should leave "
         "them out before triangulating.")),
    "threshold_too_strict": (
        "confident detections left out",
        ("detections whose confidence is above Thres were left out: look at the comparison that selects "
         "the detections, and at keypoints seen confidently in only two views.")),
}


def mistake(code: str, evidence: str = "") -> Mistake:
    """The catalogue's Mistake ``code``, with the figures that gave it away."""
    if code not in KNOWN_MISTAKES:
        raise ValueError(f"code: expected one of {sorted(KNOWN_MISTAKES)}, got {code!r}")
    name, hint = KNOWN_MISTAKES[code]
    return Mistake(code, name, hint, evidence)


# ----------------------------------------------------------------------------- small tools

def _unit(A) -> np.ndarray | None:
    A = np.asarray(A, dtype=float)
    n = np.linalg.norm(A)
    return A / n if np.isfinite(n) and n > 0 else None


def same_up_to_scale(A, B, rtol: float = 1e-6) -> bool:
    """True when A and B (same shape) agree up to a non-zero scale and sign, to ``rtol`` of their norm."""
    a, b = _unit(A), _unit(B)
    if a is None or b is None or a.shape != b.shape:
        return False
    return min(np.abs(a - b).max(), np.abs(a + b).max()) <= rtol


def epipolar_statistic(F, pts1, pts2, statistic: str = "max") -> float:
    """The largest ("max") or root-mean-square ("rms") symmetric epipolar distance, pixels; inf for no F."""
    if statistic not in ("max", "rms"):
        raise ValueError(f"statistic: expected 'max' or 'rms', got {statistic!r}")
    d = symmetric_epipolar_distances(F, pts1, pts2)
    if len(d) == 0:
        return np.inf
    return float(np.max(d)) if statistic == "max" else float(np.sqrt(np.mean(d ** 2)))


def _rotation_angle_deg(Ra, Rb) -> float:
    c = (np.trace(Ra.T @ Rb) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def _angle_deg(u, v) -> float:
    nu, nv = np.linalg.norm(u), np.linalg.norm(v)
    if nu == 0 or nv == 0:
        return 180.0
    return float(np.degrees(np.arccos(np.clip(np.dot(u, v) / (nu * nv), -1.0, 1.0))))


# ----------------------------------------------------------------------------- Q2: F

_SWAP = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def _f_repairs(M: float):
    """Maps undoing one mistake each: applied to the student's F, they give the intended F."""
    T = np.diag([1.0 / M, 1.0 / M, 1.0])
    return {
        "f_transposed": lambda F: F.T,
        "f_not_unscaled": lambda F: T @ F @ T,
        "f_unscaled_wrong_way": lambda F: T @ T @ F @ T @ T,
        "xy_swapped": lambda F: _SWAP @ F @ _SWAP,
    }


def fundamental_mistakes(F, pts1, pts2, M, tol_px: float = 0.01, statistic: str = "max") -> list[Mistake]:
    """Known mistakes that explain why F misses exact matches.

    Parameters
    ----------
    F : (3, 3) the student's fundamental matrix.
    pts1, pts2 : (N, 2) matches, pixels (x, y); exact (noise-free) ones make the verdict sharp.
    M : the scale the student was given (max of width and height).
    tol_px : F fits when the ``statistic`` ("max" or "rms") of the symmetric epipolar distances
        (core.geometry) is at most this.  For noisy matches use "rms" and the fit's goal; a
        repair must then also beat F itself.

    Returns
    -------
    [] when F already fits or nothing in the catalogue explains it; otherwise the mistakes
    (one, or a pair) whose undoing makes F fit.  Transposition, missing or inverted unscaling
    and swapped x/y are tried alone, then in pairs.
    """
    if statistic not in ("max", "rms"):
        raise ValueError(f"statistic: expected 'max' or 'rms', got {statistic!r}")
    F = np.asarray(F, dtype=float)

    def dist(G):
        return epipolar_statistic(G, pts1, pts2, statistic)

    own = dist(F) if F.shape == (3, 3) else 0.0
    if F.shape != (3, 3) or own <= tol_px:
        return []
    repairs = _f_repairs(float(M))
    for size in (1, 2):
        for codes in combinations(repairs, size):
            if {"f_not_unscaled", "f_unscaled_wrong_way"} <= set(codes):
                continue
            G = F
            for c in codes:
                G = repairs[c](G)
            d = dist(G)
            if d <= tol_px and d < own:
                ev = (f"undoing it, the {statistic} epipolar distance of the matches is "
                      f"{d:.2g} px instead of {own:.3g} px")
                return [mistake(c, ev) for c in codes]
    return []


def rank2_not_enforced(F, M: float = 1.0, rtol: float = 1e-6) -> Mistake | None:
    """Mistake when F (3, 3) has full rank: its smallest singular value above ``rtol`` times the middle one.

    The ratio is measured on diag(M, M, 1) F diag(M, M, 1), the F of the points divided by M,
    where the singular values are of comparable size (pixel units squeeze them apart).
    """
    F = np.asarray(F, dtype=float)
    if F.shape != (3, 3) or not np.all(np.isfinite(F)):
        return None
    S = np.diag([float(M), float(M), 1.0])
    s = np.linalg.svd(S @ F @ S, compute_uv=False)
    if s[1] == 0:
        return None
    ratio = s[2] / s[1]
    return mistake("f_rank3", f"s3/s2 = {ratio:.2g}") if ratio > rtol else None


def uint16_wraparound(F_uint16, F_float, rtol: float = 1e-6) -> Mistake | None:
    """Mistake when the same points fitted as uint16 and as float give different F's.

    Parameters
    ----------
    F_uint16 : (3, 3) F fitted on uint16 points (the data files' dtype).
    F_float : (3, 3) F fitted on the same points cast to float64.

    A correct fit depends on the values only; integer arithmetic that wraps around (differences
    below 0, products above 65535) makes the uint16 fit differ.
    """
    A, B = np.asarray(F_uint16, float), np.asarray(F_float, float)
    if A.shape != (3, 3) or B.shape != (3, 3) or _unit(B) is None:
        return None
    if _unit(A) is None or not same_up_to_scale(A, B, rtol):
        return mistake("uint16_wraparound", "the same points as uint16 and as float give different F's")
    return None


# ----------------------------------------------------------------------------- Q3.1: E

def essential_mistakes(E, F, K1, K2, rtol: float = 1e-6) -> list[Mistake]:
    """The mistake whose formula gives the student's E, when it is not K2^T F K1.

    Parameters
    ----------
    E : (3, 3) the student's essential matrix.  F : (3, 3) the F it was given.
    K1, K2 : (3, 3) intrinsics of camera 1 and 2.

    Formulas that coincide with the right one (K1 == K2 makes the order irrelevant) are not
    reported.  Returns [] or a one-element list.
    """
    E, F, K1, K2 = (np.asarray(a, dtype=float) for a in (E, F, K1, K2))
    if E.shape != (3, 3) or same_up_to_scale(E, K2.T @ F @ K1, rtol):
        return []
    right = K2.T @ F @ K1
    inv1, inv2 = np.linalg.inv(K1), np.linalg.inv(K2)
    candidates = [
        ("e_k_order", "K1^T F K2", K1.T @ F @ K2),
        ("e_missing_k", "F K1", F @ K1),
        ("e_missing_k", "K2^T F", K2.T @ F),
        ("e_missing_k", "F itself", F),
        ("e_missing_k", "K1^T F", K1.T @ F),
        ("e_missing_k", "F K2", F @ K2),
        ("e_inverse_k", "K2^-T F K1^-1", inv2.T @ F @ inv1),
        ("e_inverse_k", "K1^-T F K2^-1", inv1.T @ F @ inv2),
        ("e_same_k", "K1^T F K1", K1.T @ F @ K1),
        ("e_same_k", "K2^T F K2", K2.T @ F @ K2),
        ("e_transposed", "the transpose of the essential matrix", right.T),
    ]
    for code, formula, G in candidates:
        if not same_up_to_scale(G, right, rtol) and same_up_to_scale(E, G, rtol):
            return [mistake(code, f"your E equals {formula} up to scale")]
    return []


# ----------------------------------------------------------------------------- Q3.2: err

def error_not_sum_of_squares(err, res1, res2=None, rtol: float = 1e-4, *, only_named: bool = False) -> Mistake | None:
    """Mistake when ``err`` is not the sum of squared reprojection errors of both images.

    Parameters
    ----------
    err : the error the student reported (a number).
    res1, res2 : (N, 2) reprojection residuals x - proj(C, w) in image 1 and image 2, computed
        from the student's own points w.  res2 None: ``res1`` (K, 2) holds every observation
        used, of any number of views (Q6), so no variant about one image or point pairs is tried.
    only_named : return None unless err is one of the known variants (a mean, a root...): where
        the caller cannot know which observations the student meant to use (Q6's detections), an
        err that matches nothing may be a right sum over other observations, and naming it "not the
        sum of squares" would mislead.

    The evidence names the quantity err matches (a mean, a root, one image only...) when one does.
    """
    try:
        e = float(np.asarray(err, dtype=float).reshape(()))
    except (TypeError, ValueError):
        return mistake("error_not_sum_of_squares", f"err should be one number, got {type(err).__name__}")
    d1 = np.sum(np.asarray(res1, float) ** 2, axis=1)
    d2 = np.sum(np.asarray(res2, float) ** 2, axis=1) if res2 is not None else np.zeros(0)
    d = np.concatenate([d1, d2])
    total = float(d.sum())
    if np.isclose(e, total, rtol=rtol, atol=1e-9):
        return None
    n = len(d1)
    variants = {
        "the mean squared distance over observations": total / max(len(d), 1),
        "the square root of the sum of squares": np.sqrt(total),
        "the sum of distances (not squared)": float(np.sqrt(d).sum()),
        "the mean distance": float(np.sqrt(d).mean()) if len(d) else 0.0,
        "the root mean square distance": float(np.sqrt(d.mean())) if len(d) else 0.0,
        "half the sum of squares (scipy's cost)": total / 2,
    }
    if res2 is not None:
        # Only two views observed point by point tell a mean over points, or one image, apart.
        variants.update({
            "the mean over points of both squared distances": total / max(n, 1),
            "the sum of squares of image 1 only": float(d1.sum()),
            "the sum of squares of image 2 only": float(d2.sum()),
        })
    for what, value in variants.items():
        if np.isclose(e, value, rtol=rtol, atol=1e-9):
            return mistake("error_not_sum_of_squares", f"err = {e:.6g} is {what}; the sum of squares is {total:.6g}")
    if only_named:
        return None
    return mistake("error_not_sum_of_squares", f"err = {e:.6g}, but your points give a sum of squares of {total:.6g}")


def _dehomogenising_factors(w, C1, pts1, C2, pts2) -> np.ndarray:
    """Per point, the h (N,) for which w_i / h projects closest to its matches (least squares).

    (w_i, h) as a homogeneous point projects through C to (a1 + b1 h) / (a3 + b3 h) with
    a = C[:, :3] w_i and b = C[:, 3]; setting that to the pixel is linear in h.
    """
    w = np.asarray(w, float)
    num, den = np.zeros(len(w)), np.zeros(len(w))
    for C, p in ((C1, pts1), (C2, pts2)):
        C, p = np.asarray(C, float), np.asarray(p, float)
        a, b = w @ C[:, :3].T, C[:, 3]
        for j in (0, 1):
            d = p[:, j] * b[2] - b[j]
            n = a[:, j] - p[:, j] * a[:, 2]
            num += n * d
            den += d * d
    with np.errstate(all="ignore"):
        return num / den


def _differ(factors) -> bool:
    """The factors (N,) differ from point to point (a common factor, e.g. -1, is another mistake)."""
    f = np.asarray(factors, float)
    return len(f) > 1 and float(np.ptp(f)) > 1e-3 * float(np.max(np.abs(f)))


def w_not_divided(w, X=None, cameras=None, rtol: float = 1e-4) -> Mistake | None:
    """Mistake when each point of w (N, 3) is a right point times its own factor (w = X[:3] of a
    homogeneous solution X never divided by X[3]).

    X : (N, 3) the true points (noise-free matches): w_i is then parallel to X_i.
    cameras : (C1, pts1, C2, pts2) instead (noisy matches): w_i / h_i, with h_i fitted to the
        matches, reprojects far better than w_i.
    Not reported when the factors are all equal (to 1e-3): one factor for all the points (1, or
    -1 for mirrored points) is not this mistake.
    """
    w = np.asarray(w, float)
    if w.ndim != 2 or w.shape[1] != 3 or len(w) == 0 or not np.all(np.isfinite(w)):
        return None
    if X is not None:
        X = np.asarray(X, float)
        if X.shape != w.shape:
            return None
        with np.errstate(all="ignore"):
            c = np.sum(w * X, axis=1) / np.sum(X * X, axis=1)
            off = np.linalg.norm(w - c[:, None] * X, axis=1) / np.maximum(np.linalg.norm(w, axis=1), 1e-300)
        if np.all(np.isfinite(c)) and np.all(off <= rtol) and _differ(c):
            return mistake("w_not_divided", f"every row of w is the true point times a factor between "
                                            f"{np.min(c):.2g} and {np.max(c):.2g}")
        return None
    if cameras is None:
        return None
    C1, pts1, C2, pts2 = cameras
    h = _dehomogenising_factors(w, C1, pts1, C2, pts2)
    if not np.all(np.isfinite(h)) or np.any(h == 0) or not _differ(h):
        return None

    def total(v):
        from core.geometry import project

        with np.errstate(all="ignore"):
            r = np.concatenate([np.asarray(pts1, float) - project(C1, v), np.asarray(pts2, float) - project(C2, v)])
            return float(np.sum(r ** 2))

    own, divided = total(w), total(w / h[:, None])
    if np.isfinite(divided) and divided <= 0.25 * own:
        return mistake("w_not_divided", f"dividing each row of w by its own factor ({np.min(h):.2g} to "
                                        f"{np.max(h):.2g}) brings the error from {own:.3g} to {divided:.3g} px^2")
    return None


# ----------------------------------------------------------------------------- Q3.3: M2

def points_behind_cameras(w, M1, M2, max_share: float = 0.5) -> Mistake | None:
    """Mistake when more than ``max_share`` of the points w (N, 3) are behind camera M1 or M2 (3x4)."""
    w = np.asarray(w, dtype=float)
    if w.ndim != 2 or w.shape[1] != 3 or len(w) == 0:
        return None
    with np.errstate(invalid="ignore"):
        z1, z2 = depths(M1, w), depths(M2, w)
    behind = ~((z1 > 0) & (z2 > 0))
    if behind.mean() > max_share:
        return mistake("points_behind", f"{int(behind.sum())} of {len(w)} points have a negative depth")
    return None


def wrong_camera(M2, M2_true, tol_deg: float = 1.0) -> Mistake | None:
    """Mistake when M2 (3x4) is one of the other three camera2 candidates of the true pose.

    The candidates are those of ``starter.camera2`` for E = [t]x R of ``M2_true``; translations
    are compared by direction, since E fixes t only up to scale.
    """
    M2, M2_true = np.asarray(M2, float), np.asarray(M2_true, float)
    if M2.shape != (3, 4) or not np.all(np.isfinite(M2)):
        return None
    R, t = M2_true[:, :3], M2_true[:, 3]
    cands = camera2(skew(t) @ R)
    errs = [max(_rotation_angle_deg(M2[:, :3], cands[:, :3, i]), _angle_deg(M2[:, 3], cands[:, 3, i]))
            for i in range(cands.shape[2])]
    truth = [max(_rotation_angle_deg(R, cands[:, :3, i]), _angle_deg(t, cands[:, 3, i]))
             for i in range(cands.shape[2])]
    best, right = int(np.argmin(errs)), int(np.argmin(truth))
    if errs[best] <= tol_deg and best != right:
        rot = _rotation_angle_deg(M2[:, :3], R)
        return mistake("wrong_camera", f"your M2 is another candidate: rotation {rot:.0f} deg away, "
                                       f"t at {_angle_deg(M2[:, 3], t):.0f} deg from the true direction")
    return None


def one_camera_depth(M2, M2_true, X, tol_deg: float = 1.0) -> Mistake | None:
    """Mistake when M2 (3x4) is a camera2 candidate of the true pose that reconstructs every true point
    X (N, 3) in front of one camera and behind the other (the twisted pair, or its mirror).

    Such a candidate passes a depth test of one camera alone; the other wrong ones put the points
    behind camera 1 (or both).  The exact normalised projections x1, x2 of X meet under M2 = [R | t]
    where lam R x1 + t is parallel to x2 (noise-free, the rays meet): lam is the depth in camera 1,
    and the third coordinate of lam R x1 + t the depth in camera 2.  (No triangulation of Q3.2's
    kind: this ships with the public checks.)
    """
    M2, M2_true, X = np.asarray(M2, float), np.asarray(M2_true, float), np.asarray(X, float)
    if M2.shape != (3, 4) or X.ndim != 2 or X.shape[1:] != (3,) or len(X) == 0 or not np.all(np.isfinite(M2)):
        return None
    if wrong_camera(M2, M2_true, tol_deg) is None:
        return None
    x1 = X / X[:, 2:]
    x2 = X @ M2_true[:, :3].T + M2_true[:, 3]          # a multiple of the normalised projection: enough
    rotated = x1 @ M2[:, :3].T                          # R x1, per point
    # x2 x (lam R x1 + t) = 0  =>  lam = -(x2 x t) . (x2 x R x1) / |x2 x R x1|^2
    across = np.cross(x2, rotated)
    with np.errstate(divide="ignore", invalid="ignore"):
        z1 = -np.sum(np.cross(x2, M2[:, 3]) * across, axis=1) / np.sum(across * across, axis=1)
        z2 = z1 * rotated[:, 2] + M2[2, 3]
    for front, behind, a, b in ((z1, z2, 1, 2), (z2, z1, 2, 1)):
        if np.all(front > 0) and np.all(behind < 0):
            return mistake("depth_one_camera", f"your M2 puts all {len(X)} points in front of camera {a} "
                                               f"and behind camera {b}")
    return None


# ----------------------------------------------------------------------------- Q4.1: matches

def points_xy_swapped(pts, pts_true, tol_px: float = 3.0) -> Mistake | None:
    """Mistake when the points (N, 2) match pts_true (N, 2) far better with x and y exchanged."""
    p, q = np.asarray(pts, float), np.asarray(pts_true, float)
    if p.shape != q.shape or p.ndim != 2 or p.shape[1] != 2 or len(p) == 0:
        return None
    straight = np.mean(np.linalg.norm(p - q, axis=1) <= tol_px)
    swapped = np.mean(np.linalg.norm(p[:, ::-1] - q, axis=1) <= tol_px)
    if swapped >= 0.5 and swapped > 2 * straight:
        return mistake("xy_swapped", f"{swapped:.0%} of the points are right once x and y are exchanged, "
                                     f"{straight:.0%} as returned")
    return None


# ----------------------------------------------------------------------------- Q5: BA

def residual_layout(res, res_expected, rtol: float = 1e-6) -> Mistake | None:
    """Mistake when ``res`` holds the expected residual values (up to sign) in another order.

    res, res_expected : (4N,) the student's residuals and the handout's
    [(p1 - p1_hat).ravel(), (p2 - p2_hat).ravel()] at the same x.
    """
    r, e = np.asarray(res, float).ravel(), np.asarray(res_expected, float).ravel()
    if r.shape != e.shape:
        return None
    scale = max(np.abs(e).max(initial=0.0), 1e-12)
    if min(np.abs(r - e).max(), np.abs(r + e).max()) <= rtol * scale:
        return None
    if np.allclose(np.sort(np.abs(r)), np.sort(np.abs(e)), rtol=rtol, atol=rtol * scale):
        return mistake("residual_layout", "your residuals hold the right values in another order")
    return None


def ba_mistakes(o1, o2, t_init, t_final, rel_drop: float = 1e-9, min_scale: float = 0.2) -> list[Mistake]:
    """Known bundle-adjustment failures.

    Parameters
    ----------
    o1, o2 : the reprojection errors before and after, as the student's code reported or
        as recomputed from its results.
    t_init, t_final : (3,) camera 2's translation at the start and at the end.
    rel_drop : o2 must be below o1 (1 - rel_drop).
    min_scale : |t_final| below min_scale |t_init| is a collapse.
    """
    out = []
    o1, o2 = float(o1), float(o2)
    if not (np.isfinite(o2) and o2 < o1 * (1.0 - rel_drop)):
        out.append(mistake("ba_not_decreasing", f"o1 = {o1:.6g}, o2 = {o2:.6g}"))
    n0, n1 = np.linalg.norm(t_init), np.linalg.norm(t_final)
    if n0 > 0 and np.isfinite(n1) and n1 < min_scale * n0:
        out.append(mistake("ba_scale_collapse", f"|t| went from {n0:.3g} to {n1:.3g}"))
    return out


# ----------------------------------------------------------------------------- Q6: Thres

def threshold_mistakes(P, P_true, conf, Thres, tol: float, step: float = 100.0) -> list[Mistake]:
    """Threshold mistakes in a multiview reconstruction, on data built to reveal them.

    Parameters
    ----------
    P : (N, 3) the student's points.  P_true : (N, 3) the true points.
    conf : (N, V) confidences of the detections of each point in the V views.
    Thres : the threshold the student was given.
    tol : a point is right when within this distance of the truth (NaN is never right).
    step : a detection with Thres < confidence <= Thres + step is "just above" the threshold.

    The caller's data must make every detection with confidence <= Thres wrong by a clear
    margin, every other one exact, and give every point at least two views above Thres.  Then:
    points whose wrong detection sits exactly at Thres come out wrong with ``>=``; points with a
    wrong detection below Thres come out wrong when the threshold is ignored; points that need a
    detection just above Thres come out wrong or missing when the test is too strict.
    """
    P, P_true, conf = (np.asarray(a, float) for a in (P, P_true, conf))
    if P.shape != P_true.shape or conf.ndim != 2 or conf.shape[0] != len(P):
        return []
    wrong = ~(np.linalg.norm(P - P_true, axis=1) <= tol)
    just_above = np.any((conf > Thres) & (conf <= Thres + step), axis=1)
    at = np.any(conf == Thres, axis=1) & ~np.any(conf < Thres, axis=1) & ~just_above
    below = np.any(conf < Thres, axis=1) & ~np.any(conf == Thres, axis=1) & ~just_above

    def share(mask):
        return (int(wrong[mask].sum()), int(mask.sum())) if mask.any() else (0, 0)

    # Ignoring the threshold also uses the detections at Thres: the wider mistake is named alone.
    k, n = share(below)
    if n and k > n / 2:
        return [mistake("threshold_ignored", f"{k} of {n} points whose wrong detection is below "
                                             "Thres came out wrong")]
    k, n = share(at)
    if n and k > n / 2:
        return [mistake("threshold_inclusive", f"{k} of {n} points whose wrong detection has a "
                                               "confidence of exactly Thres came out wrong")]
    k, n = share(just_above)
    if n and k > n / 2:
        return [mistake("threshold_too_strict", f"{k} of {n} points that need a detection just above "
                                                "Thres came out wrong or missing")]
    return []
