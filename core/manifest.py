"""The homework's questions, points, notebooks and the functions each question is about.

One table read by everything that needs to know the homework's shape: the notebook builder, the
autograder (which functions to look for, how many points), the PDF export (which question titles
start a page, which functions the code bundle must define) and the README.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["GIVEN_HELPERS", "Question", "QUESTIONS", "NOTEBOOKS", "question", "functions_of_notebook", "QUESTION_HEADING"]


@dataclass(frozen=True)
class Question:
    """One gradable question.

    id: the handout's label ("Q3.2"); title: a short title of the kit's own; points: the handout's
    points; notebook: the stem of the notebook that answers it; functions: the names the student
    writes for it (empty for a written answer); by_hand: graded by a person from the PDF;
    extra_credit: not counted in the base total.
    """

    id: str
    title: str
    points: int
    notebook: str
    functions: tuple[str, ...] = ()
    by_hand: bool = False
    extra_credit: bool = False


QUESTIONS: tuple[Question, ...] = (
    Question("Q1.1", "Fixating cameras and f33", 5, "q1_proofs", by_hand=True),
    Question("Q1.2", "Relative pose, E and F from odometry", 5, "q1_proofs", by_hand=True),
    Question("Q2", "The eight-point algorithm", 10, "q2_eightpoint", ("eightpoint",)),
    Question("Q3.1", "The essential matrix", 5, "q3_metric_reconstruction", ("essentialMatrix",)),
    Question("Q3.2", "Triangulation", 10, "q3_metric_reconstruction", ("triangulate",)),
    Question("Q3.3", "Choosing the second camera", 10, "q3_metric_reconstruction", ("findM2",)),
    Question("Q4.1", "Matching along the epipolar line", 15, "q4_temple_3d", ("epipolarCorrespondence",)),
    Question("Q4.2", "The temple in 3D", 5, "q4_temple_3d", ("compute3D_pts",)),
    Question("Q5", "RANSAC and bundle adjustment", 20, "q5_bundle_adjustment",
             ("rodriguesResidual", "bundleAdjustment")),
    Question("Q6", "Three-view keypoints of a moving car", 15, "q6_multiview_car",
             ("MultiviewReconstruction", "plot_3d_keypoint_video"), extra_credit=True),
)

NOTEBOOKS: tuple[str, ...] = tuple(dict.fromkeys(q.notebook for q in QUESTIONS))

# The helpers the kit gives (starter, the course's helper.py) that a question's functions call, by
# the questions that use them.  A student who defines one of these names replaces the given one in
# what is graded; the feedback of these questions says so (autograder.hidden.plugin).
GIVEN_HELPERS: dict[str, tuple[str, ...]] = {
    "refineF": ("Q2",),
    "camera2": ("Q3.3",),
    "ransacF": ("Q5",),
    "rodrigues": ("Q5",),
    "invRodrigues": ("Q5",),
}

# A markdown cell whose first line matches this starts a question (the PDF starts a page there).
QUESTION_HEADING = r"^#{1,3}\s*(Q\d+(?:\.\d+)?)\b"


def question(qid: str) -> Question:
    """The Question whose id is ``qid`` (ValueError naming the known ids otherwise)."""
    for q in QUESTIONS:
        if q.id == qid:
            return q
    raise ValueError(f"qid: expected one of {[q.id for q in QUESTIONS]}, got {qid!r}")


def functions_of_notebook(stem: str) -> tuple[str, ...]:
    """Names of the functions a student writes in the notebook ``stem`` (e.g. "q2_eightpoint")."""
    if stem not in NOTEBOOKS:
        raise ValueError(f"stem: expected one of {list(NOTEBOOKS)}, got {stem!r}")
    return tuple(f for q in QUESTIONS if q.notebook == stem for f in q.functions)
