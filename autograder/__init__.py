"""The autograder: hidden tests on unseen scenes, student code run only in a sandbox.

Public entry points (imported lazily, so that ``import autograder`` stays cheap):

- :func:`grade_submission` (``autograder.grade``): one submission -> ``SubmissionResult``;
- :func:`grade_batch`: many submissions in parallel into an output folder;
- :func:`build_hidden_inputs` (``autograder.tests``): the hidden inputs of a ``GradingConfig``;
- :func:`load_config` (``autograder.config``);
- :func:`main` (``autograder.__main__``): the command line, ``python -m autograder``.
"""

from __future__ import annotations

__all__ = ["build_hidden_inputs", "grade_batch", "grade_submission", "load_config", "main"]

_WHERE = {
    "grade_submission": "grade", "grade_batch": "grade", "build_hidden_inputs": "tests",
    "load_config": "config", "main": "__main__",
}


def __getattr__(name):
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(f"{__name__}.{_WHERE[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
