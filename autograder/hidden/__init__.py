"""The hidden checks, as pytest tests: ``python -m pytest autograder/hidden --submission PATH``.

One test per check, worth the points of its ``@pytest.mark.points(value, question=..., name=...)``
marker; the student's functions are called through a sandbox session (the ``student`` fixture)
and judged in the pytest process by ``judging/<concept>.py``.  ``test_<concept>.py`` holds a
concept's tests and a session fixture that makes its calls once (several checks judge the same
outputs).  ``plugin.py`` holds the fixtures and turns test reports into the results model;
``worker.py`` runs one pytest session after another for the grader.  What the checks are given
lives in ``autograder/inputs/`` (the hidden scenes, each concept's cases, made once per run) and
what they say in ``autograder/feedback/words.py``.  The CLI, Gradescope and the nbgrader course all grade a submission by running
these tests (``autograder.grading.run.GradingRun``).
"""
