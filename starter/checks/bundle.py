"""Public checks of Q5: ``rodriguesResidual`` and ``bundleAdjustment``; every verdict is judging.bundle's."""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from core.geometry import IDENTITY_POSE
from judging import bundle as jb
from starter.rotations import invRodrigues, rodrigues
from starter.slow_call import watched

from ._common import finish, read_or_report, run_failed, stop_if_not_implemented
from ._scenes import NO_DEFAULT_DATA, PUBLIC_SEED, NoisyPair, two_view
from .report import CheckReport, call

__all__ = ["BAProblem", "RESIDUAL_FILE", "check_bundleAdjustment", "check_rodriguesResidual", "residual_inputs",
           "residual_cases"]

# The residuals of the public inputs' x misread (judging.bundle.misreadings): computing them needs
# the handout's residual, which cannot ship, so ``python -m kit check-data`` writes them here.
RESIDUAL_FILE = Path(__file__).with_name("residual_case.json")

_N_RESIDUAL = 20
# A handout-style BFGS (numerical gradients over 3N + 6 unknowns) slows down steeply with N:
# about 1 s for 12 points here, 10 s for 20, 25 s for 30.
_N_BA = 12
# A call longer than this is said to be slow while it runs (starter.slow_call); one longer than
# _NOTE_SECONDS gets a note in the report, since the notebook's run has ten times the points.
_SLOW_SECONDS = 5.0
_NOTE_SECONDS = 1.0


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


def residual_inputs(tv: NoisyPair) -> list[tuple[str, tuple]]:
    """(label, (K1, M1, p1, K2, p2, x)) of the check on the pair ``tv``: its first points at the true x
    = [X.ravel(), r2, t2], with the exact matches and with the noisy (uint16) ones."""
    pair = tv.pair
    k = slice(0, _N_RESIDUAL)
    x = _pack(pair.X[k], pair.M2)
    return [("exact matches", (pair.K1, IDENTITY_POSE, pair.pts1[k], pair.K2, pair.pts2[k], x)),
            ("noisy matches", (pair.K1, IDENTITY_POSE, tv.pts1_u16[k].astype(float), pair.K2,
                               tv.pts2_u16[k].astype(float), x))]


@lru_cache(maxsize=1)
def _public_misread() -> dict:
    return json.loads(RESIDUAL_FILE.read_text(encoding="utf-8"))["misread"]


def residual_cases(tv: NoisyPair, misread: dict | None = None) -> list[tuple[str, jb.ResidualCase]]:
    """(label, ResidualCase) of :func:`residual_inputs`.  At the true x every projection is the
    pair's exact one, so the handout's residuals are the matches less those projections; the
    residuals of x misread come from ``misread`` (label -> order -> (4N,); none when None)."""
    pair = tv.pair
    k = slice(0, _N_RESIDUAL)
    out = []
    for label, args in residual_inputs(tv):
        p1, p2 = np.asarray(args[2], float), np.asarray(args[4], float)
        expected = np.concatenate([(p1 - pair.pts1[k]).ravel(), (p2 - pair.pts2[k]).ravel()])
        other = {order: np.array(r, float) for order, r in (misread or {}).get(label, {}).items()}
        out.append((label, jb.ResidualCase(args, expected, other)))
    return out


def check_rodriguesResidual(rodriguesResidual, *, scene: NoisyPair | None = None, inputs=None, root=None,
                            verbose: bool = True) -> CheckReport:
    """Evaluate ``rodriguesResidual`` at the true configuration of a generated scene.

    Parameters
    ----------
    rodriguesResidual : the student's function (K1, M1, p1 (N, 2), K2, p2 (N, 2), x) -> (4N,)
        residuals, x = [w.ravel(), r2 (3,), t2 (3,)].
    scene : the pair to check on (default: the public generated pair).
    inputs : instead, the judging.bundle.ResidualCase's to check on (inputs with the residuals they
        must give).
    root : accepted like every check's; this one needs no data.
    verbose : print the report.

    Checked (judging.bundle.residuals): exactly the handout's [(p1 - p1_hat).ravel(), (p2 -
    p2_hat).ravel()] (an overall sign is accepted): zero at the true x for exact matches.  On the
    public pair, residuals of x read in another order are named (x_packing).
    """
    report = CheckReport("rodriguesResidual")
    if inputs is None:
        cases = residual_cases(scene or two_view(), None if scene is not None else _public_misread())
    else:
        cases = [(f"input {k}", case) for k, case in enumerate(inputs, start=1)]
        if not all(isinstance(c, jb.ResidualCase) for _, c in cases):
            raise ValueError("inputs: expected judging.bundle.ResidualCase's (inputs with their residuals), got "
                             f"{sorted({type(c).__name__ for _, c in cases})}")
    for k, (where, case) in enumerate(cases):
        inp = tuple(np.array(a, float) for a in case.args)
        out = call(rodriguesResidual, *(a.copy() for a in inp))
        if k == 0 and stop_if_not_implemented(report, out):
            return finish(report, verbose)
        if run_failed(report, out, where):
            continue
        r = read_or_report(report, jb.read_residuals, out.value, len(inp[2]), label=f"returns 4N residuals ({where})")
        if r is not None:
            report.judged(jb.residuals(r, case), where)
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


def problem_of_scene(tv: NoisyPair) -> BAProblem:
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

    Timed (starter.slow_call): past a few seconds a line printed while it runs says so and names
    the faster route; a run over a second, and a SciPy optimiser that reports failure, get a note.
    """
    report = CheckReport("bundleAdjustment")
    notes = []
    if problems is None:
        problems = [problem_of_scene(scene or two_view())]
        if scene is None:
            notes.append(NO_DEFAULT_DATA)
    report.notes.extend(notes)
    timed = watched(bundleAdjustment, name="bundleAdjustment", after=_SLOW_SECONDS, report_failures=False)
    for k, pr in enumerate(problems):
        out = call(timed, np.array(pr.K1, float), IDENTITY_POSE.copy(), np.array(pr.p1, float),
                   np.array(pr.K2, float), np.array(pr.M2_init, float), np.array(pr.p2, float),
                   np.array(pr.w_init, float))
        watch = timed.last_watch
        if watch is not None and watch.seconds > _NOTE_SECONDS:
            used_minimize = any(name == "minimize" for name, _ in watch.results)
            report.notes.append(f"bundleAdjustment took {watch.seconds:.1f} s on {len(pr.p1)} points ({pr.label})"
                                + ("; scipy.optimize.least_squares on the residual vector is much faster than "
                                   "minimize on their summed squares" if used_minimize else ""))
        report.notes.extend(watch.failures() if watch is not None else [])
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
