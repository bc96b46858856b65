"""Q3.1: ``essentialMatrix(F, K1, K2)`` against E = K2^T F K1 up to scale and sign (judging.essential).

Inputs: three random rank-2 F's with random intrinsics K1 != K2 (so swapped, missing or inverted
K's all show), and the true F of an exact two-view scene, whose E must have two equal singular
values and a zero one.
"""

from __future__ import annotations

import pytest

from autograder.inputs.cases import SECONDS
from autograder.feedback.words import read_returned
from judging import essential as je
from judging.verdict import Malformed


@pytest.fixture(scope="session")
def essential(hidden):
    """The prepared inputs (``autograder.inputs.essential.Essential``)."""
    return hidden.prepared["essential"]


@pytest.fixture(scope="session")
def essential_E(student, essential) -> list:
    """The student's E (or the Malformed) for each input, then for the true F: one request."""
    inputs = [*essential.inputs, essential.true_F]
    outcomes = student.each("essentialMatrix", inputs, seconds=SECONDS["essentialMatrix"])
    out = []
    for args, o in zip(inputs, outcomes):
        try:
            out.append(read_returned("essentialMatrix", o, je.read_E, args))
        except Malformed as exc:
            out.append(exc)
    return out


@pytest.fixture(scope="session")
def essential_verdicts(essential, essential_E) -> list:
    """judging.essential.essential of each random input's E (the Malformed where there is none)."""
    return [E if isinstance(E, Malformed) else je.essential(E, *inp) for inp, E in zip(essential.inputs, essential_E)]


def _mistakes(verdicts) -> list:
    return next((list(v.mistakes) for v in verdicts if not isinstance(v, Malformed) and v.mistakes), [])


@pytest.mark.points(4, question="Q3.1", name="E = K2^T F K1 on hidden F, K1, K2")
def test_E_is_K2T_F_K1(essential_verdicts, score):
    lines = [f"input {k}: {v if isinstance(v, Malformed) else v.sentence}"
             for k, v in enumerate(essential_verdicts, start=1)]
    right = sum(not isinstance(v, Malformed) and v.passed for v in essential_verdicts)
    score.grade(right / len(essential_verdicts), lines, _mistakes(essential_verdicts))


@pytest.mark.points(1, question="Q3.1", name="E of a true F has two equal singular values and a zero one")
def test_E_of_a_true_F_has_singular_values_s_s_0(essential_E, essential_verdicts, score):
    E = essential_E[-1]
    if isinstance(E, Malformed):
        score.grade(0.0, [f"from a true F: {E}"])
    v = je.singular_values(E)
    score.grade(float(v.passed), [f"from a true F: {v.sentence}"], _mistakes(essential_verdicts))
