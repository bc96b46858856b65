"""The autograder: hidden checks (pytest tests) on unseen scenes, student code run only in a sandbox.

Layout, one folder a role, each importing only the rows below it (docs/architecture.md):
``sandbox/`` (the locked-down child and the session with it) and ``submission/`` (reading a
hand-in); ``inputs/`` (the configuration, the hidden scenes and each concept's cases) and
``feedback/`` (the results model, the words of a failed call, the pictures, the feedback page);
``review/`` (look-alike code, library calls, the class report); ``grading/`` (a run set up once,
one worker session per submission, the budget, the canary); ``hidden/`` (the hidden checks as
pytest tests and their plugin); ``channels/`` (the batch, Gradescope, nbgrader and a cluster).
This root holds only the command line, ``__main__.py``.

Public entry points (imported lazily, so that ``import autograder`` stays cheap):

- :class:`GradingRun` (``autograder.grading.run``): set up once, ``run.grade(path)`` -> a finished ``SubmissionResult``;
- :func:`grade_batch` (``autograder.channels.batch``): many submissions in parallel into an output folder;
- :func:`build_hidden_inputs` (``autograder.inputs.build``): the hidden inputs of a ``GradingConfig``;
- :func:`load_config` (``autograder.inputs.config``);
- :func:`main` (``autograder.__main__``): the command line, ``python -m autograder``.
"""

from __future__ import annotations

__all__ = ["GradingRun", "build_hidden_inputs", "grade_batch", "load_config", "main"]

_WHERE = {
    "GradingRun": "grading.run", "grade_batch": "channels.batch", "build_hidden_inputs": "inputs.build",
    "load_config": "inputs.config", "main": "__main__",
}


def __getattr__(name):
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(f"{__name__}.{_WHERE[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
