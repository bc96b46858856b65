"""Q5: bundle adjustment of camera 2 and the points, rotation parameterised by a Rodrigues vector.

The residual is written out here (``rodriguesResidual`` and its helper ``_residuals``): the answer
key prints these bodies (kit/notebooks copies a reference function with its helpers).  It is the
kit's one residual: what else needs it is grader-side and calls it (the hidden tests' optimum,
solutions.expected's residuals for the judgments); nothing that ships computes it
(tests/repository/test_behaviour_leaks.py).
"""

from __future__ import annotations

import numpy as np
import scipy.optimize

from core.geometry import project
from core.validate import as_matrix, as_points, same_length
from starter import invRodrigues, rodrigues

__all__ = ["rodriguesResidual", "bundleAdjustment"]


def rodriguesResidual(K1, M1, p1, K2, p2, x):
    """Reprojection residuals of the points and camera 2 packed in ``x``.

    Parameters
    ----------
    K1, K2 : (3, 3) intrinsics.  M1 : (3, 4) camera 1's [R | t] (held fixed).
    p1, p2 : (N, 2) observed pixels (x, y) in image 1 and image 2.
    x : (3N + 6,) = [w.ravel() (N points, x y z each), r2 (3,) Rodrigues vector of camera 2's
        rotation, t2 (3,) its translation]; camera 2 is M2 = [rodrigues(r2) | t2].

    Returns
    -------
    residuals : (4N,) = [(p1 - p1_hat).ravel(), (p2 - p2_hat).ravel()]: its squared norm is the
        total reprojection error of ``triangulate``.
    """
    p1 = as_points(p1, "p1")
    p2 = as_points(p2, "p2")
    n = same_length(p1=p1, p2=p2)
    x = np.asarray(x, dtype=float).ravel()
    if x.size != 3 * n + 6:
        raise ValueError(f"x: expected 3N + 6 = {3 * n + 6} values for N = {n} points, got {x.size}")
    C1 = as_matrix(K1, "K1", (3, 3)) @ as_matrix(M1, "M1", (3, 4))
    return _residuals(C1, as_matrix(K2, "K2", (3, 3)), p1, p2, x)


def _residuals(C1, K2, p1, p2, x):
    # rodriguesResidual without the input checks, for the optimiser's many calls.
    n = len(p1)
    w = x[:3 * n].reshape(n, 3)
    M2 = np.hstack([rodrigues(x[3 * n:3 * n + 3]), x[3 * n + 3:, None]])
    return np.concatenate([(p1 - project(C1, w)).ravel(), (p2 - project(K2 @ M2, w)).ravel()])


def _jacobian(fun, z, n, f0):
    """Forward-difference Jacobian (4N, 3N + k) of the residuals in 3 + k evaluations.

    Point i moves only its own four residuals, so the x (then y, then z) coordinates of every
    point can be nudged in one evaluation; each of the k camera parameters gets its own.
    """
    J = np.zeros((f0.size, z.size))
    rows = (2 * np.arange(n)[:, None] + np.array([0, 1, 2 * n, 2 * n + 1])[None, :])  # (N, 4)
    cols = 3 * np.arange(n)
    for j in range(3):
        step = 1e-6 * np.maximum(1.0, np.abs(z[cols + j]))
        zz = z.copy()
        zz[cols + j] += step
        J[rows, (cols + j)[:, None]] = ((fun(zz) - f0)[rows]) / step[:, None]
    for j in range(3 * n, z.size):
        step = 1e-6 * max(1.0, abs(z[j]))
        zz = z.copy()
        zz[j] += step
        J[:, j] = (fun(zz) - f0) / step
    return J


def bundleAdjustment(K1, M1, p1, K2, M2_init, p2, w_init):
    """Jointly refine camera 2's extrinsics and the 3D points to minimise the reprojection error.

    Parameters
    ----------
    K1, K2 : (3, 3) intrinsics.  M1 : (3, 4) camera 1's [R | t], held fixed.
    p1, p2 : (N, 2) observed pixels (x, y) in image 1 and image 2 (RANSAC inliers).
    M2_init : (3, 4) initial [R | t] of camera 2 (from findM2), world -> camera 2.
    w_init : (N, 3) initial world points.

    Returns
    -------
    M2 : (3, 4) refined [R | t];  w : (N, 3) refined points;
    o1, o2 : total squared reprojection error (pixels^2) before and after, the squared norm of
        ``rodriguesResidual`` at the start and at the end.

    Method (answer key only)
    ------------------------
    Solved with scipy.optimize.least_squares (Levenberg-Marquardt); the residuals of a point
    depend on that point and camera 2 only, so the Jacobian costs 3 + 5 evaluations.  The scale of the scene is
    free (points and t can shrink together), so |t2| is held at its initial value.
    """
    K1 = as_matrix(K1, "K1", (3, 3))
    K2 = as_matrix(K2, "K2", (3, 3))
    M1 = as_matrix(M1, "M1", (3, 4))
    M2_init = as_matrix(M2_init, "M2_init", (3, 4))
    p1 = as_points(p1, "p1")
    p2 = as_points(p2, "p2")
    w_init = as_points(w_init, "w_init", dims=3)
    n = same_length(p1=p1, p2=p2, w_init=w_init)
    t0 = M2_init[:, 3]
    scale = np.linalg.norm(t0)
    if scale == 0:
        raise ValueError("M2_init: the translation is zero, so the two cameras coincide and depth is undetermined")
    # The gauge: points and t can shrink together without changing any projection, so t moves
    # on the sphere of radius |t0| only, through two coordinates u of its tangent plane at t0.
    t_dir = t0 / scale
    tangent = np.linalg.svd(t_dir[None, :])[2][1:].T          # (3, 2), orthonormal, normal to t0

    def unpack(z):
        d = t_dir + tangent @ z[-2:]
        return np.concatenate([z[:-2], scale * d / np.linalg.norm(d)])

    C1 = K1 @ M1
    z0 = np.concatenate([w_init.ravel(), invRodrigues(M2_init[:, :3]), np.zeros(2)])

    def fun(z):
        return _residuals(C1, K2, p1, p2, unpack(z))

    o1 = float(np.sum(fun(z0) ** 2))
    # Levenberg-Marquardt with an exact linear solve at each step: a few iterations from the
    # RANSAC start, where a trust region with an iterative (lsmr) solve wandered for hundreds.
    res = scipy.optimize.least_squares(fun, z0, jac=lambda z: _jacobian(fun, z, n, fun(z)), method="lm",
                                       x_scale="jac")
    x = unpack(res.x)
    M2 = np.hstack([rodrigues(x[3 * n:3 * n + 3]), x[3 * n + 3:, None]])
    w = x[:3 * n].reshape(n, 3)
    o2 = float(np.sum(res.fun ** 2))
    return M2, w, o1, o2
