"""Public checks of Q5: ``rodriguesResidual`` and ``bundleAdjustment``; every verdict is judging.bundle's."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.geometry import IDENTITY_POSE
from judging import bundle as jb
from starter.rotations import invRodrigues, rodrigues

from ._common import finish, read_or_report, run_failed, stop_if_not_implemented
from ._scenes import NO_DEFAULT_DATA, PUBLIC_SEED, NoisyPair, two_view
from .report import CheckReport, call

__all__ = ["BAProblem", "check_bundleAdjustment", "check_rodriguesResidual"]

_N_RESIDUAL = 20
# A handout-style BFGS (numerical gradients over 3N + 6 unknowns) slows down steeply with N:
# about 1 s for 12 points here, 10 s for 20, 25 s for 30.
_N_BA = 12


@dataclass(frozen=True, eq=False)
class BAProblem:
    """One bundle adjustment: K1, K2 (3, 3), matches p1, p2 (N, 2), the start M2_init (3, 4) and
    w_init (N, 3), and ``optimum``, the lowest total squared error known (None: unknown)."""

    label: str
    K1: np.ndarray
    K2: np.ndarray
    p1: np.ndarray
    p2: np.ndarray
    M2_init: np.ndarray
    w_init: np.ndarray
    optimum: float | None


def _pack(w, M2) -> np.ndarray:
    return np.concatenate([np.asarray(w, float).ravel(), invRodrigues(M2[:, :3]), M2[:, 3]])


def check_rodriguesResidual(rodriguesResidual, *, scene: NoisyPair | None = None, inputs=None, root=None,
                            verbose: bool = True) -> CheckReport:
    """Evaluate ``rodriguesResidual`` at the true configuration of a generated scene.

    Parameters
    ----------
    rodriguesResidual : the student's function (K1, M1, p1 (N, 2), K2, p2 (N, 2), x) -> (4N,)
        residuals, x = [w.ravel(), r2 (3,), t2 (3,)].
    scene : the pair to check on (default: the public generated pair).
    inputs : instead, the (K1, M1, p1, K2, p2, x) tuples to check on.
    root : accepted like every check's; this one needs no data.
    verbose : print the report.

    Checked (judging.bundle.residuals): exactly the handout's [(p1 - p1_hat).ravel(), (p2 -
    p2_hat).ravel()] (an overall sign is accepted): zero at the true x for exact matches.
    """
    report = CheckReport("rodriguesResidual")
    if inputs is None:
        tv = scene or two_view()
        pair = tv.pair
        k = slice(0, _N_RESIDUAL)
        x = _pack(pair.X[k], pair.M2)
        inputs = [("exact matches", (pair.K1, IDENTITY_POSE, pair.pts1[k], pair.K2, pair.pts2[k], x)),
                  ("noisy matches", (pair.K1, IDENTITY_POSE, tv.pts1_u16[k].astype(float), pair.K2,
                                     tv.pts2_u16[k].astype(float), x))]
    else:
        inputs = [(f"input {k}", inp) for k, inp in enumerate(inputs, start=1)]
    for k, (where, inp) in enumerate(inputs):
        inp = tuple(np.array(a, float) for a in inp)
        out = call(rodriguesResidual, *(a.copy() for a in inp))
        if k == 0 and stop_if_not_implemented(report, out):
            return finish(report, verbose)
        if run_failed(report, out, where):
            continue
        r = read_or_report(report, jb.read_residuals, out.value, len(inp[2]), label=f"returns 4N residuals ({where})")
        if r is not None:
            report.judged(jb.residuals(r, *inp), where)
    return finish(report, verbose)


def _start(pair, n, rng):
    """A perturbed start: camera 2 turned by 0.5 deg, t by 1 deg (same length), points moved by 0.5%."""
    axis = rng.normal(size=3)
    R0 = rodrigues(np.deg2rad(0.5) * axis / np.linalg.norm(axis)) @ pair.M2[:, :3]
    axis = np.cross(pair.M2[:, 3], rng.normal(size=3))
    t0 = rodrigues(np.deg2rad(1.0) * axis / np.linalg.norm(axis)) @ pair.M2[:, 3]
    depth = np.linalg.norm(pair.X[:n], axis=1, keepdims=True)
    w0 = pair.X[:n] + rng.normal(0.0, 0.005, (n, 3)) * depth
    return np.hstack([R0, t0[:, None]]), w0


def _generated_problem(tv: NoisyPair) -> BAProblem:
    pair, n = tv.pair, _N_BA
    M2_init, w_init = _start(pair, n, np.random.default_rng(PUBLIC_SEED))
    p1, p2 = tv.pts1_u16[:n].astype(float), tv.pts2_u16[:n].astype(float)
    # The true configuration is one candidate, so the optimum is at most its error.
    o_true = jb.total_error(pair.K1, pair.K2, p1, p2, pair.M2, pair.X[:n])
    return BAProblem("generated", pair.K1, pair.K2, p1, p2, M2_init, w_init, o_true)


def check_bundleAdjustment(bundleAdjustment, *, scene: NoisyPair | None = None, problems=None, root=None,
                           verbose: bool = True) -> CheckReport:
    """Run ``bundleAdjustment`` from a perturbed start of a generated scene.

    Parameters
    ----------
    bundleAdjustment : the student's function (K1, M1, p1, K2, M2_init, p2, w_init) ->
        (M2, w, o1, o2), o1 and o2 the total squared reprojection errors before and after.
    scene : the pair to make the generated problem from (default: the public generated pair).
    problems : instead, the BAProblems (or objects with the same fields) to check on.
    root : accepted like every check's; the default data are not used (a start would need a
        reference answer).
    verbose : print the report.

    Checked (judging.bundle): the reprojection error of the returned M2 and w reaches the
    optimum (at most the true configuration's error on the generated scene) and the reconstruction keeps its shape (any scale or gauge is right); M2 holds a rotation;
    o1 and o2 are the errors of the start and of the result.
    """
    report = CheckReport("bundleAdjustment")
    notes = []
    if problems is None:
        problems = [_generated_problem(scene or two_view())]
        if scene is None:
            notes.append(NO_DEFAULT_DATA)
    report.notes.extend(notes)
    for k, pr in enumerate(problems):
        out = call(bundleAdjustment, np.array(pr.K1, float), IDENTITY_POSE.copy(), np.array(pr.p1, float),
                   np.array(pr.K2, float), np.array(pr.M2_init, float), np.array(pr.p2, float),
                   np.array(pr.w_init, float))
        if k == 0 and stop_if_not_implemented(report, out):
            return finish(report, verbose)
        if run_failed(report, out, pr.label):
            continue
        got = read_or_report(report, jb.read_ba, out.value, len(pr.p1),
                             label=f"returns (M2 (3x4), w (N, 3), o1, o2) ({pr.label})")
        if got is None:
            continue
        M2, w, o1, o2 = got
        args = (pr.K1, pr.K2, pr.p1, pr.p2, pr.M2_init, pr.w_init)
        report.judged(jb.result(M2, w, *args, pr.optimum), pr.label)
        report.judged(jb.rotation(M2), pr.label)
        report.judged(jb.reported_errors(o1, o2, M2, w, *args), pr.label)
    return finish(report, verbose, bundleAdjustment, root)
