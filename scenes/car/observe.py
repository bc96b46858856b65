"""Visibility of the keypoints (ray tests against the car's parts) and the observation model:
confidence and pixel noise."""

from __future__ import annotations

import numpy as np

from core.geometry import project

from .model import N_KEYPOINTS, Part

# --------------------------------------------------------------------------------------------
# Visibility and the observation model
# --------------------------------------------------------------------------------------------

def _segment_hits(part: Part, a: np.ndarray, b: np.ndarray, stop: float) -> bool:
    """Does the segment a -> b (car frame), up to ``stop`` metres before b, cross the part's interior?"""
    d = b - a
    length = np.linalg.norm(d)
    hi = 1.0 - stop / length
    lo = 0.0
    # Shrinking the solid by a millimetre keeps rays that graze a face or an edge visible.
    num = part.offsets - 1e-3 - part.normals @ a
    den = part.normals @ d
    for nu, de in zip(num, den):
        if abs(de) < 1e-12:
            if nu < 0:
                return False
        elif de > 0:
            hi = min(hi, nu / de)
        else:
            lo = max(lo, nu / de)
        if lo >= hi:
            return False
    return True


def keypoint_normals(parts, kps: np.ndarray) -> list[np.ndarray]:
    """For each keypoint (car frame), the outward normals (n, 3) of the faces it lies on."""
    out = []
    for p in kps:
        normals = []
        for part in parts:
            dist = part.normals @ p - part.offsets
            if np.all(dist <= 1e-6):
                normals.extend(part.normals[np.abs(dist) <= 1e-6])
        if not normals:
            raise RuntimeError(f"keypoint {p} lies on no face of the car model")
        out.append(np.array(normals))
    return out


def confidence_sigma(confidence, sigma_best: float = 0.5, sigma_worst: float = 12.0) -> np.ndarray:
    """Standard deviation (pixels, per axis) of the detection error at a given confidence.

    Geometric interpolation from ``sigma_worst`` at 300 to ``sigma_best`` at 1100, so every
    step of 100 multiplies the error by the same factor (about 1.49 with the defaults).

    Parameters
    ----------
    confidence : array_like
        Confidences, in [300, 1100].

    Returns
    -------
    ndarray, the shape of ``confidence``
    """
    c = np.asarray(confidence, float)
    frac = (1100.0 - c) / 800.0
    return sigma_best * (sigma_worst / sigma_best) ** frac


def observe_keypoints(rng, parts, kp_normals, kps_car, R_car, pos, centres, C, width, height,
             sigma_best, sigma_worst):
    """Projections, occlusion flags and noisy observations of one time step.

    Returns uv (3, 12, 2), occluded (3, 12) bool, pts (3, 12, 3) int64.
    """
    world = pos + kps_car @ R_car.T
    uv = np.stack([project(Cc, world) for Cc in C])
    occluded = np.zeros((len(C), N_KEYPOINTS), bool)
    quality = np.zeros((len(C), N_KEYPOINTS))
    for c, centre in enumerate(centres):
        cam = R_car.T @ (centre - pos)
        for k, p in enumerate(kps_car):
            occluded[c, k] = any(_segment_hits(part, cam, p, 0.005) for part in parts)
            v = (cam - p) / np.linalg.norm(cam - p)
            quality[c, k] = max(0.0, float(np.max(kp_normals[k] @ v)))
    raw = 400 + 700 * quality + rng.normal(0, 100, quality.shape)
    conf_visible = np.clip(np.round(raw / 100) * 100, 500, 1100)
    conf_hidden = rng.choice([300, 400, 500], size=quality.shape, p=[0.45, 0.4, 0.15])
    conf = np.where(occluded, conf_hidden, conf_visible).astype(np.int64)
    sigma = confidence_sigma(conf, sigma_best, sigma_worst)
    noisy = uv + rng.normal(size=uv.shape) * sigma[..., None]
    xy = np.round(noisy)
    # A detector only reports pixels inside the image.
    xy[..., 0] = np.clip(xy[..., 0], 0, width - 1)
    xy[..., 1] = np.clip(xy[..., 1], 0, height - 1)
    pts = np.concatenate([xy.astype(np.int64), conf[..., None]], axis=-1)
    return uv, occluded, pts
