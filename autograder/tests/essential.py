"""Q3.1: ``essentialMatrix(F, K1, K2)`` against E = K2^T F K1, up to scale and sign.

Inputs: three random rank-2 F's with random intrinsics K1 != K2 (so swapped, missing or
inverted K's all show), and the true F of an exact two-view scene, whose E must have two equal
singular values and a zero one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from autograder.results import QuestionResult
from autograder.sandbox import Call
from starter.checks.mistakes import essential_mistakes, same_up_to_scale

from ._common import Malformed, Outcome, as_array, fmt, graded
from .hidden import Scenes

__all__ = ["FUNCTIONS", "QUESTIONS", "calls", "judge", "prepare"]

QUESTIONS = ("Q3.1",)
FUNCTIONS = ("essentialMatrix",)
_CALL = "Q3.1:essentialMatrix"
_SECONDS_PER_CALL = 2.0
_RTOL = 1e-6


@dataclass(frozen=True, eq=False)
class Prepared:
    inputs: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]   # (F, K1, K2), the last a true F


def _random_K(rng) -> np.ndarray:
    f = rng.uniform(300, 2000)
    return np.array([[f, rng.uniform(-2, 2), rng.uniform(150, 500)],
                     [0.0, f * rng.uniform(0.95, 1.05), rng.uniform(100, 400)],
                     [0.0, 0.0, 1.0]])


def _random_F(rng) -> np.ndarray:
    U = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    V = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    F = U @ np.diag([1.0, rng.uniform(0.2, 0.9), 0.0]) @ V.T
    return F / np.linalg.norm(F)


def prepare(scenes: Scenes) -> Prepared:
    rng = np.random.default_rng(scenes.config.seed("essential") % 2**63)
    inputs = [(_random_F(rng), _random_K(rng), _random_K(rng)) for _ in range(3)]
    tv = scenes.two_view
    inputs.append((tv.F, tv.K1, tv.K2))
    return Prepared(tuple(inputs))


def calls(p: Prepared, time_scale: float) -> list[Call]:
    items = [(inp, {}) for inp in p.inputs]
    budget = _SECONDS_PER_CALL * len(items) * time_scale
    return [Call(_CALL, "__hw4_each", ("essentialMatrix", items, budget), timeout=budget + 2)]


def _gap(E, G) -> float:
    a, b = E / np.linalg.norm(E), G / np.linalg.norm(G)
    return float(min(np.abs(a - b).max(), np.abs(a + b).max()))


def judge(p: Prepared, outcomes) -> list[QuestionResult]:
    items = Outcome(outcomes.get(_CALL), "essentialMatrix").items(len(p.inputs))
    right, lines, mistakes = 0, [], []
    formula_inputs = p.inputs[:-1]
    for k, ((F, K1, K2), item) in enumerate(zip(formula_inputs, items), start=1):
        try:
            if not item.ok:
                raise Malformed(item.error)
            E = as_array(item.value, (3, 3), "E")
        except Malformed as exc:
            lines.append(f"input {k}: {exc}")
            continue
        expected = K2.T @ F @ K1
        if np.all(np.isfinite(E)) and np.any(E) and same_up_to_scale(E, expected, _RTOL):
            right += 1
            lines.append(f"input {k}: E = K2^T F K1 up to scale")
        else:
            gap = _gap(E, expected) if np.all(np.isfinite(E)) and np.any(E) else float("inf")
            lines.append(f"input {k}: E differs from K2^T F K1 (largest difference of the unit-norm "
                         f"matrices {fmt(gap)}, goal <= {_RTOL:g})")
            mistakes = mistakes or essential_mistakes(E, F, K1, K2, _RTOL)

    sv_lines, sv_ok = [], False
    try:
        item = items[-1]
        if not item.ok:
            raise Malformed(item.error)
        E = as_array(item.value, (3, 3), "E")
        if not np.all(np.isfinite(E)) or not np.any(E):
            raise Malformed("E is zero or not finite")
        s = np.linalg.svd(E, compute_uv=False)
        ratio2, ratio3 = s[1] / s[0], s[2] / s[0]
        sv_ok = ratio2 >= 1 - 1e-6 and ratio3 <= 1e-6
        sv_lines.append(f"from a true F: s2/s1 = 1 - {fmt(1 - ratio2)} and s3/s1 = {fmt(ratio3)} "
                        "(goal: s2/s1 within 1e-6 of 1, s3/s1 below 1e-6)")
    except Malformed as exc:
        sv_lines.append(f"from a true F: {exc}")
    tests = [
        graded("E = K2^T F K1 on hidden F, K1, K2", 4, right / len(formula_inputs), lines, mistakes),
        graded("E of a true F has two equal singular values and a zero one", 1, float(sv_ok), sv_lines, mistakes),
    ]
    return [QuestionResult.of("Q3.1", tests)]
