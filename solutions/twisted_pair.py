"""Q3.3's twisted-pair case: matches on which a findM2 that tests depth in camera 1 only goes wrong.

Grader side: its construction runs working linear triangulations (answers to Q3.2), so it cannot
ship.  The hidden test (autograder.inputs.pose) makes the case of each draw's seed; the
public self-check reads the public seed's case from ``starter/checks/twisted_pair.json``, written
by ``python -m kit check-data`` (kit.check_data), and a test proves that file is a fresh
computation.

Of camera2's four candidates, the "twisted pair" (camera 2 turned half a turn about the
baseline, t kept) puts a point in front of camera 1 and behind camera 2 exactly when the point
is farther from camera 1's centre than from camera 2's.  A findM2 that keeps the candidates with
every point in front of camera 1, then the smallest reprojection error, chooses between the
right candidate and the twisted one by error alone: on ordinary data the two linear
triangulations differ by a fraction of a percent (either may win), so the mistake goes unseen.

This case makes it visible deterministically.  Camera 2 moves forward (every point beyond the
plane halfway between the centres, so the twisted pair keeps every point in front of camera 1),
and the matches lie near the epipoles, where linear triangulation is ill-conditioned and the
twisted pair's reprojects clearly better.  Each match is drawn (from a numpy Generator of the
caller's seed) and kept only when, for every linear triangulation of ``TRIANGULATIONS``:

- the right candidate puts its point in front of both cameras;
- the twisted pair puts it in front of camera 1 and behind camera 2, the two others behind camera 1;
- the twisted pair's reprojection error is below ``MARGIN`` times the right candidate's.

So every correct findM2 (depth in both cameras, all points or most of them, any of these
triangulations) chooses the right candidate, and the camera-1-only rule the twisted pair.
The linear triangulations' errors here differ from the optimal one by far more than the usual
slack: the case judges the camera only, not w.

Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera, camera 1 is [I | 0];
C = K M; F maps points of image 1 to lines of image 2 (x2^T F x1 = 0).
"""

from __future__ import annotations

import numpy as np

from core.geometry import CameraPair, IDENTITY_POSE, depths, project
from starter.checks.twisted_pair import TwistedPairCase
from starter.pose import camera2

__all__ = ["MARGIN", "TRIANGULATIONS", "TwistedPairCase", "candidate_roles", "twisted_pair_case"]

MARGIN = 0.8            # the twisted pair's linear error is below MARGIN times the right candidate's
WIDTH, HEIGHT = 640, 480
_BORDER = 40.0          # every match at least this far (pixels) from the image border
_BATCH = 400            # candidate matches drawn at a time
_MAX_BATCHES = 200


# ------------------------------------------------------------------------ linear triangulations

def _rows(C1, p1, C2, p2) -> np.ndarray:
    """(N, 4, 4): the rows x C[2] - C[0], y C[2] - C[1] of both cameras, per match."""
    return np.stack([p1[:, :1] * C1[2] - C1[0], p1[:, 1:] * C1[2] - C1[1],
                     p2[:, :1] * C2[2] - C2[0], p2[:, 1:] * C2[2] - C2[1]], axis=1)


def _dehomogenise(X) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return X[:, :3] / X[:, 3:]


def _svd(A) -> np.ndarray:
    return _dehomogenise(np.linalg.svd(A)[2][:, -1, :])


def _unit_rows(C1, p1, C2, p2):
    A = _rows(C1, p1, C2, p2)
    return _svd(A / np.linalg.norm(A, axis=2, keepdims=True))


def _plain(C1, p1, C2, p2):
    return _svd(_rows(C1, p1, C2, p2))


def _eigh(C1, p1, C2, p2):
    A = _rows(C1, p1, C2, p2)
    return _dehomogenise(np.linalg.eigh(np.swapaxes(A, 1, 2) @ A)[1][:, :, 0])


def _inhomogeneous(C1, p1, C2, p2):
    A = _rows(C1, p1, C2, p2)
    return np.linalg.solve(np.swapaxes(A[:, :, :3], 1, 2) @ A[:, :, :3],
                           -(np.swapaxes(A[:, :, :3], 1, 2) @ A[:, :, 3:]))[:, :, 0]


def _hartley(C1, p1, C2, p2):
    # Each image's points moved to their centroid and scaled to a mean distance of sqrt(2).
    out = []
    for C, p in ((C1, p1), (C2, p2)):
        c = p.mean(axis=0)
        s = np.sqrt(2.0) / max(float(np.mean(np.linalg.norm(p - c, axis=1))), 1e-12)
        T = np.array([[s, 0.0, -s * c[0]], [0.0, s, -s * c[1]], [0.0, 0.0, 1.0]])
        out += [T @ C, (p - c) * s]
    return _plain(*out)


# name -> triangulate(C1 (3, 4), pts1 (N, 2), C2 (3, 4), pts2 (N, 2)) -> w (N, 3): the linear
# methods students write (the reference's is the first; Hartley's normalises over all matches).
TRIANGULATIONS = {
    "SVD, rows scaled to unit norm": _unit_rows,
    "SVD of A": _plain,
    "eigenvector of A^T A": _eigh,
    "least squares with w4 = 1": _inhomogeneous,
    "SVD, points normalised (Hartley)": _hartley,
}


def _errors(C1, p1, C2, p2, w) -> np.ndarray:
    with np.errstate(all="ignore"):
        return np.sum((p1 - project(C1, w)) ** 2, axis=1) + np.sum((p2 - project(C2, w)) ** 2, axis=1)


# ------------------------------------------------------------------------ the case

def candidate_roles(M2) -> tuple[np.ndarray, int, int]:
    """(camera2's candidates (3, 4, 4) of E = [t]x R of M2 (3, 4), index of M2's, index of its twisted pair)."""
    from core.geometry import essential_from_pose

    M2 = np.asarray(M2, float)
    cands = camera2(essential_from_pose(M2))
    t = M2[:, 3] / np.linalg.norm(M2[:, 3])
    gaps = [np.abs(cands[:, :3, i] - M2[:, :3]).max() + np.abs(cands[:, 3, i] - t).max() for i in range(4)]
    right = int(np.argmin(gaps))
    # The twisted pair keeps t and has the other rotation.
    twisted = next(i for i in range(4) if i != right and np.allclose(cands[:, 3, i], cands[:, 3, right])
                   and not np.allclose(cands[:, :3, i], cands[:, :3, right]))
    return cands, right, twisted


def _geometry(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K1, K2, M2 with |t| = 1): camera 2 ahead of camera 1, its epipole inside image 1."""
    f1 = rng.uniform(700.0, 900.0)
    K1 = np.array([[f1, 0.0, WIDTH / 2 + rng.normal(0, 5)], [0.0, f1, HEIGHT / 2 + rng.normal(0, 5)], [0, 0, 1.0]])
    K2 = K1.copy()
    K2[:2, :2] *= rng.uniform(1.05, 1.2)            # K1 != K2, so that they cannot be confused unnoticed
    K2[:2, 2] += rng.uniform(-10.0, 10.0, 2)
    # Mostly forward, partly sideways: the epipole sits 80-180 px from image 1's centre.
    angle, turn = rng.uniform(0.1, 0.2), rng.uniform(0.0, 2 * np.pi)
    c2 = np.array([np.sin(angle) * np.cos(turn), np.sin(angle) * np.sin(turn), np.cos(angle)])
    # Camera 2 turned a few degrees from camera 1's orientation.
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    a = rng.uniform(0.02, 0.06)
    S = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + np.sin(a) * S + (1 - np.cos(a)) * S @ S
    return K1, K2, np.hstack([R, (-R @ c2)[:, None]])


def _inside(p) -> np.ndarray:
    return ((p[:, 0] >= _BORDER) & (p[:, 0] <= WIDTH - _BORDER) & (p[:, 1] >= _BORDER)
            & (p[:, 1] <= HEIGHT - _BORDER))


def _judge(K1, K2, cands, right, twisted, p1, p2, methods) -> tuple[np.ndarray, np.ndarray]:
    """(per match: every rule of the module doc holds under ``methods``; per method: the ratio of the
    twisted pair's total error to the right candidate's over all the matches)."""
    C1 = K1 @ IDENTITY_POSE
    ok = np.ones(len(p1), bool)
    ratios = []
    for method in methods:
        ws = [method(C1, p1, K2 @ cands[:, :, i], p2) for i in range(4)]
        with np.errstate(invalid="ignore"):
            z1 = [w[:, 2] > 0 for w in ws]
            z2 = [depths(cands[:, :, i], w) > 0 for i, w in enumerate(ws)]
        e_right = _errors(C1, p1, K2 @ cands[:, :, right], p2, ws[right])
        e_twisted = _errors(C1, p1, K2 @ cands[:, :, twisted], p2, ws[twisted])
        ok &= z1[right] & z2[right] & z1[twisted] & ~z2[twisted] & (e_twisted < MARGIN * e_right)
        for i in set(range(4)) - {right, twisted}:
            ok &= ~z1[i]
        ratios.append(float(np.sum(e_twisted) / np.sum(e_right)))
    return ok, np.array(ratios)


def twisted_pair_case(seed: int, n: int = 12, noise_px: float = 2.0) -> TwistedPairCase:
    """The twisted-pair case of ``seed`` (any int): ``n`` matches, Gaussian noise of ``noise_px``.

    Deterministic in its arguments.  Matches are drawn near the epipole and kept one by one while
    the module doc's rules hold under every per-match triangulation; then the set is checked as a
    whole (Hartley's normalisation depends on all the matches) and drawn again if it fails.
    """
    rng = np.random.default_rng(np.random.SeedSequence([abs(int(seed)), 0x7715]))
    K1, K2, M2 = _geometry(rng)
    cands, right, twisted = candidate_roles(M2)
    baseline = -M2[:, :3].T @ M2[:, 3]               # camera 2's centre, |baseline| = 1
    per_match = [m for name, m in TRIANGULATIONS.items() if "Hartley" not in name]
    for _ in range(_MAX_BATCHES):
        X, p1, p2 = [], [], []
        for _ in range(_MAX_BATCHES):
            # Directions within about 1 degree of the baseline, 3 to 8 baselines away: near the
            # epipoles, where the linear triangulations of the right and twisted pair part.
            u = baseline + 0.015 * rng.normal(size=(_BATCH, 3))
            Xb = u / np.linalg.norm(u, axis=1, keepdims=True) * rng.uniform(3.0, 8.0, (_BATCH, 1))
            exact = CameraPair(K1, K2, M2, Xb)
            q1 = exact.pts1 + rng.normal(0.0, noise_px, (_BATCH, 2))
            q2 = exact.pts2 + rng.normal(0.0, noise_px, (_BATCH, 2))
            ok, _ = _judge(K1, K2, cands, right, twisted, q1, q2, per_match)
            ok &= _inside(q1) & _inside(q2) & _inside(exact.pts1) & _inside(exact.pts2)
            keep = np.flatnonzero(ok)[: n - len(X)]
            X += list(Xb[keep])
            p1 += list(q1[keep])
            p2 += list(q2[keep])
            if len(X) == n:
                break
        X, p1, p2 = np.array(X), np.array(p1), np.array(p2)
        if len(X) < n:
            break
        ok, ratios = _judge(K1, K2, cands, right, twisted, p1, p2, list(TRIANGULATIONS.values()))
        if ok.all() and ratios.max() < MARGIN:
            return TwistedPairCase(CameraPair(K1, K2, M2, X), p1, p2, cands[:, :, twisted].copy(),
                                   float(ratios.max()))
    raise RuntimeError(f"twisted_pair_case: no case found for seed {seed}")  # pragma: no cover
