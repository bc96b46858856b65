"""The hidden checks, as pytest tests: ``python -m pytest autograder/hidden --submission PATH``.

One test per check, worth the points of its ``@pytest.mark.points(value, question=..., name=...)``
marker; the student's functions are called through a sandbox session (the ``student`` fixture)
and judged in the pytest process by ``judging/<concept>.py``.  ``test_<concept>.py`` holds a
concept's tests and a session fixture that makes its calls once (several checks judge the same
outputs).  ``plugin.py`` holds the fixtures and turns test reports into the results model;
``scenes.py`` makes the hidden scenes, ``cases/`` (one module per concept) cuts every concept's inputs from them (with
the reference's results), ``inputs.py`` makes and caches them once per batch; ``feedback.py``
words failed calls and merges feedback lines; ``worker.py`` runs one pytest session after another
for the grader.  The CLI, Gradescope and the nbgrader course all grade a submission by running
these tests (``autograder.run.GradingRun``).
"""
