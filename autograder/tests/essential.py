"""Q3.1: ``essentialMatrix(F, K1, K2)`` against E = K2^T F K1, up to scale and sign.

Every verdict is judging.essential's.  Inputs: three random rank-2 F's with random intrinsics K1 != K2 (so swapped, missing or
inverted K's all show), and the true F of an exact two-view scene, whose E must have two equal
singular values and a zero one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from autograder.results import QuestionResult
from autograder.hidden.legacy import Call
from judging import essential as je
from judging.verdict import Malformed

from ._common import Outcome, graded
from .hidden import Scenes

__all__ = ["FUNCTIONS", "QUESTIONS", "calls", "judge", "prepare"]

QUESTIONS = ("Q3.1",)
FUNCTIONS = ("essentialMatrix",)
_CALL = "Q3.1:essentialMatrix"
_SECONDS_PER_CALL = 2.0


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


def _E(item) -> np.ndarray:
    if not item.ok:
        raise Malformed(item.error)
    return je.read_E(item.value)


def judge(p: Prepared, outcomes) -> list[QuestionResult]:
    items = Outcome(outcomes.get(_CALL), "essentialMatrix").items(len(p.inputs))
    right, lines, mistakes = 0, [], []
    formula_inputs = p.inputs[:-1]
    for k, ((F, K1, K2), item) in enumerate(zip(formula_inputs, items), start=1):
        try:
            v = je.essential(_E(item), F, K1, K2)
        except Malformed as exc:
            lines.append(f"input {k}: {exc}")
            continue
        right += v.passed
        lines.append(f"input {k}: {v.sentence}")
        mistakes = mistakes or list(v.mistakes)

    sv_lines, sv_ok = [], False
    try:
        v = je.singular_values(_E(items[-1]))
        sv_ok = v.passed
        sv_lines.append(f"from a true F: {v.sentence}")
    except Malformed as exc:
        sv_lines.append(f"from a true F: {exc}")
    tests = [
        graded("E = K2^T F K1 on hidden F, K1, K2", 4, right / len(formula_inputs), lines, mistakes),
        graded("E of a true F has two equal singular values and a zero one", 1, float(sv_ok), sv_lines, mistakes),
    ]
    return [QuestionResult.of("Q3.1", tests)]
