"""The autograder: hidden checks (pytest tests) on unseen scenes, student code run only in a sandbox.

Layout: ``sandbox/`` (isolation and the session protocol with the child), ``submission.py`` (reading
notebooks), ``hidden/`` (the hidden checks as pytest tests, their plugin and inputs), ``run.py`` (a
grading run: configuration, hidden inputs, sandboxes, workers, budget and canary set up once; every
channel grades through it), ``grade.py`` (one submission: a pytest session in a worker,
``workers.py``; its budget, ``budget.py``), ``batch.py`` (many, resumable; the folder's journal in
``journal.py``, stopping processes in ``killing.py``), ``gradebook.py`` (grades.csv), ``key.py``
(the answer-key submission), ``results.py`` (the results model), ``config.py``, ``gradescope.py``
and ``gradescope_run.py`` (building the bundle, grading in it), ``nbgrader_course.py`` and
``nbgrader_grade.py`` (building the course, grading in it), ``pictures.py`` and ``feedback_page.py``
(the figures of the public data), ``review/`` (the class report, look-alike code) and the command
line ``__main__.py``.

Public entry points (imported lazily, so that ``import autograder`` stays cheap):

- :class:`GradingRun` (``autograder.run``): set up once, ``run.grade(path)`` -> a finished ``SubmissionResult``;
- :func:`grade_batch` (``autograder.batch``): many submissions in parallel into an output folder;
- :func:`build_hidden_inputs` (``autograder.hidden.inputs``): the hidden inputs of a ``GradingConfig``;
- :func:`load_config` (``autograder.config``);
- :func:`main` (``autograder.__main__``): the command line, ``python -m autograder``.
"""

from __future__ import annotations

__all__ = ["GradingRun", "build_hidden_inputs", "grade_batch", "load_config", "main"]

_WHERE = {
    "GradingRun": "run", "grade_batch": "batch", "build_hidden_inputs": "hidden.inputs",
    "load_config": "config", "main": "__main__",
}


def __getattr__(name):
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(f"{__name__}.{_WHERE[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
