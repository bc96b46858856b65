"""The hidden checks' fixtures (``student``, ``hidden``, ``score``...) and the ``points`` marker."""

from __future__ import annotations

import pytest

pytest_plugins = ["autograder.hidden.plugin"]


@pytest.fixture(scope="session")
def legacy_judged(student, hidden):
    """``judged(module)``: the QuestionResults of a module of ``autograder/tests`` (judged once per run)."""
    from autograder.hidden.legacy import run_calls

    done: dict = {}

    def judged(module) -> dict:
        if module.__name__ not in done:
            outcomes = run_calls(student, hidden.calls(module))
            done[module.__name__] = {q.id: q for q in module.judge(hidden.prepared[module.__name__], outcomes)}
        return done[module.__name__]

    return judged
