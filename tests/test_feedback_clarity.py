"""Feedback that does not mislead (issue 16): a failed check says so in words, a repeated error is
said once with a count, the catalogue names only what its test tells apart, a student's own
definition of a given helper is noted, and NumPy 2's ragged-array error gets a hint.

Hidden checks are graded in this process (``run_here`` on a ``LocalStudent``, the hidden inputs of
the quick config) with the reference's functions and one function changed.
"""

from __future__ import annotations

import numpy as np
import pytest

import solutions
from autograder.config import quick_config
from autograder.hidden.inputs import build_hidden_inputs
from autograder.hidden.plugin import HIDDEN_DIR, LocalStudent, run_here


@pytest.fixture(scope="module")
def hidden():
    return build_hidden_inputs(quick_config())


def _reference() -> dict:
    return {name: getattr(solutions, name) for name in solutions.__all__}


def _graded(hidden, concept: str, **changed):
    """{test name: TestResult} of autograder/hidden/test_<concept>.py with ``changed`` functions."""
    result = run_here(LocalStudent(dict(_reference(), **changed)), hidden, tests=[HIDDEN_DIR / f"test_{concept}.py"])
    return {t.name: t for q in result.questions for t in q.tests}


# ------------------------------------------------------------------------------------------------
# NumPy 2's ragged-array error


def ragged_essential(F, K1, K2):
    """Stacks rows of different length, as np.array refuses since NumPy 1.24."""
    return np.array([F[0], F[1, :2], F[2]], dtype=float)


def test_ragged_array_error_gets_a_hint_in_the_hidden_feedback(hidden):
    tests = _graded(hidden, "essential", essentialMatrix=ragged_essential)
    text = "\n".join(t.feedback for t in tests.values())
    assert "inhomogeneo" in text, text               # the error itself is still quoted
    assert "different lengths or shapes" in text and "np.array" in text, text


def test_ragged_array_error_gets_a_hint_in_the_self_check():
    from starter.checks.report import call

    out = call(ragged_essential, np.eye(3), np.eye(3), np.eye(3))
    assert out.status == "error" and "different lengths or shapes" in out.message, out.message
