"""Functions and results the picture tests share: a good triangulate, a hostile eightpoint, a
result built around a student id.
"""

from __future__ import annotations

import numpy as np
from autograder.feedback.results import QuestionResult, SubmissionResult, TestResult


HOSTILE = "<script>window.pwned=1</script> =cmd|' /C calc'!A0 \x1b[31mred\x1b]8;;http://x\x07 \u202e"


def good_triangulate(C1, pts1, C2, pts2):
    return np.ones((len(pts1), 3)), 0.5


def hostile_eightpoint(pts1, pts2, M):
    raise ValueError(HOSTILE)


def result_with(feedback: str, visibility: str = "visible", student_id: str = HOSTILE) -> SubmissionResult:
    q2 = QuestionResult.of("Q2", [TestResult("eightpoint fits the matches", 0.0, 6.0, feedback=feedback,
                                             visibility=visibility),
                                  TestResult("rank 2", 4.0, 4.0)])
    q32 = QuestionResult.of("Q3.2", [TestResult("triangulate", 10.0, 10.0, visibility="hidden")])
    return SubmissionResult((q2, q32), student_id=student_id)
