"""The unscored picture step: what the student's functions do on the PUBLIC data, for the figures
of their feedback (``autograder.feedback.pictures``).

It runs only when the grader asks for pictures (``--pictures``), after every scored check (the
plugin orders the ``picture`` items last), one test per question of
``starter.checks.pictures.QUESTIONS``.  The student's functions run in the sandbox session of the
checks, each call within ``autograder.feedback.pictures.SECONDS`` of CPU time, and are called by the
parameters the student wrote (the checks' ``signatures``: another year's findM2 or
compute3D_pts gets its year's call, as in the checks); what they return is checked once and
drawn here from the checked arrays (``autograder.feedback.pictures.picture_record``: this process never
runs student code).  Whatever they do, the test passes and records either the picture or the
sentence "figure not drawn: ...".  It has no ``points`` marker: it never counts in the result.

The step runs in a fresh child of the session (``public_student``): the child of the checks was
given hidden scenes, and code that kept one could otherwise show it on the student's own page.
"""

import pytest

from autograder.feedback.pictures import contract, picture_record


def _questions() -> tuple[str, ...]:
    try:
        return tuple(contract().QUESTIONS)
    except ImportError:  # a kit without the pictures module: no step
        return ()


@pytest.fixture(scope="module")
def public_student(request):
    """The submission's student on a child that has seen the public data only (made once)."""
    student = request.getfixturevalue("student")
    student.fresh_child()
    return student


@pytest.mark.picture
@pytest.mark.parametrize("question", _questions())
def test_picture(question, request):
    config = request.config
    if not config.getoption("--pictures"):
        pytest.skip("pictures were not asked for (--pictures)")
    student = request.getfixturevalue("public_student")
    # Drawn here, in this worker (the grader's own process; student code ran in the sandbox).
    record = picture_record(student, question, signatures=request.getfixturevalue("signatures"))
    if record:  # {}: no picture of this question in the pictures module
        config.hw4.pictures[question] = record
