"""The hidden checks, as pytest tests: ``python -m pytest autograder/hidden --submission PATH``.

One test per check, worth the points of its ``@pytest.mark.points(value, question=...)`` marker;
the student's functions are called through a sandbox session (the ``student`` fixture) and judged
in the pytest process; hidden inputs come from the session fixture ``hidden``, made from the
grader's secret config.  ``plugin.py`` holds the fixtures and turns test reports into the results
model; ``inputs.py`` makes and caches the hidden inputs; ``legacy.py`` bridges to the judges of
``autograder/tests/`` not yet rewritten on ``judging/``.  The CLI, Gradescope and the nbgrader
course all grade a submission by running these tests (``autograder.grade.grade_submission``).
"""
