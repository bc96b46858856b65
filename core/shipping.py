"""Which parts of the kit ship where, written once.

Three destinations read this table:

- the student release (``python -m kit release``, :mod:`kit.release`): the packages students
  import or run, the student notebooks, the data without the official course files;
- the grader bundle (``python -m autograder gradescope``, :mod:`autograder.channels.gradescope.bundle`): what
  grading a submission needs, reference solutions included;
- the sandbox (:mod:`autograder.sandbox`): the packages the student's code may import while it
  is graded (the notebooks import ``starter``, whose self-checks import ``judging``).

Every entry is a top-level package folder of the kit (shipped whole, without caches) unless
noted.  Nothing here is imported by the packages it names.
"""

from __future__ import annotations

__all__ = [
    "STUDENT_PACKAGES",
    "STUDENT_OPTIONAL_PACKAGES",
    "STUDENT_NOTEBOOKS",
    "NEVER_TO_STUDENTS",
    "DATA_EXCLUDE",
    "GRADER_PACKAGES",
    "SANDBOX_PACKAGES",
    "SANDBOX_WITHHELD",
]

# The student release: packages shipped whole.  ``judging`` is shipped when it exists.
STUDENT_PACKAGES = ("core", "scenes", "starter", "handin")
STUDENT_OPTIONAL_PACKAGES = ("judging",)
# Of notebooks/, only the student notebooks at its top level (``<stem>.ipynb``, hand_in.ipynb).
STUDENT_NOTEBOOKS = "notebooks/*.ipynb"
# Paths (relative to the kit) that must never reach a student; the release is checked against them.
NEVER_TO_STUDENTS = ("solutions", "autograder", "kit", "tests", "benchmarks", "notebooks/key",
                     "notebooks/nbgrader", "notebooks/src", "data/official")
# Folders of data/ that stay with the instructor (dropped-in official course files).
DATA_EXCLUDE = ("official",)

# The grader bundle (Gradescope): packages shipped whole, with requirements.txt and the data.
GRADER_PACKAGES = ("core", "scenes", "starter", "judging", "solutions", "autograder")

# The sandbox's own library folder: what the student's code may import of the kit.
SANDBOX_PACKAGES = ("core", "scenes", "starter", "judging")
# Files of those packages the sandbox never gets, and hides wherever the grader's Python could find
# them: the minimisation behind refineF, which the grader computes for the code under test instead
# (autograder/sandbox/helpers.py), so that nothing in the child can polish a switched-off run.
SANDBOX_WITHHELD = ("starter/refine_polish.py",)
