"""The picture step with real sandboxes: a student function that hangs or fails there costs only
its picture ("figure not drawn: ..."), never a point.

1. In this process, on a stand-in pictures module, a real sandbox session: a hanging eightpoint
   is stopped within the question's budget and the next question's picture is still made from
   the same session.
2. A whole batch (grading worker, sandbox, the real ``starter.checks.pictures``): the answer key
   with an eightpoint that hangs on the public data only, graded with the default data left out
   of the hidden checks, keeps full marks; its feedback.html says why Q2 has no figure, and every
   other question's picture is drawn.
"""

from __future__ import annotations

import json
import time

import nbformat
import numpy as np
import pytest

import corpus
from autograder.feedback import pictures as step
from autograder.hidden.plugin import Student
from autograder.sandbox import ResourceLimits, Sandbox
import picture_standin

pytestmark = pytest.mark.slow

LIMITS = ResourceLimits(memory_bytes=2 * 2**30, processes=48, grace=1.0)

HANGING = """
import numpy as np

def eightpoint(pts1, pts2, M):
    while True:
        pass

def triangulate(C1, pts1, C2, pts2):
    raise ValueError("<script>alert(1)</script> \\x1b[31m")

def essentialMatrix(F, K1, K2):
    return K2.T @ F @ K1
"""


def test_a_hanging_function_costs_its_picture_within_the_budget(monkeypatch):
    monkeypatch.setattr(step, "contract", lambda: picture_standin)
    with Sandbox(limits=LIMITS) as box:
        session = box.session(HANGING, load_timeout=30, budget=120)
        try:
            student = Student(session)
            start = time.monotonic()
            q2 = step.picture_record(student, "Q2", seconds=2.0)
            took = time.monotonic() - start
            q32 = step.picture_record(student, "Q3.2", seconds=2.0)
            again = step.picture_record(student, "Q2", seconds=2.0)
        finally:
            session.close()
    assert q2["error"].startswith("figure not drawn: eightpoint"), q2
    assert took < 15, f"the hanging call took {took:.1f} s"
    assert q32["error"].startswith("figure not drawn: triangulate raised ValueError"), q32
    assert again["error"].startswith("figure not drawn: eightpoint"), "a stopped function is not called again"


def _public_points() -> np.ndarray:
    from starter import load_temple

    return np.asarray(load_temple().pts1, dtype=float)


def test_a_hang_on_the_public_data_costs_the_picture_never_the_grade(tmp_path):
    pytest.importorskip("starter.checks.pictures", reason="the pictures module is not in this kit yet")
    from autograder.channels.batch import grade_batch
    from autograder.inputs.config import quick_config

    first = _public_points()[:3].tolist()
    folder = corpus.build("key_full_marks", tmp_path / "subs")
    nb = nbformat.read(folder / "q2_eightpoint.ipynb", as_version=4)
    cell = next(c for c in nb.cells if c.cell_type == "code" and "def eightpoint(" in c.source)
    head, _, rest = cell.source.partition("def eightpoint(")
    signature, _, body = rest.partition("\n")
    cell.source = (f"{head}def eightpoint({signature}\n"
                   f"    import numpy as _np\n"
                   f"    if _np.shape(pts1)[-1:] == (2,) and _np.allclose(_np.asarray(pts1, float)[:3], {first}):\n"
                   f"        while True:  # the public data: hang\n"
                   f"            pass\n{body}")
    nbformat.write(nb, folder / "q2_eightpoint.ipynb")
    config = quick_config(use_default_data=False)  # the hidden checks never see the public data
    record, = grade_batch([folder], tmp_path / "out", config=config, progress=False, limits=LIMITS)
    results = json.loads((record.folder / "results.json").read_text())
    assert record.failure is None
    assert record.score == pytest.approx(sum(t["max_score"] for t in results["tests"]))
    page = (record.folder / "feedback.html").read_text()
    assert "figure not drawn: eightpoint" in page
    index = json.loads((record.folder / "figures" / "figures.json").read_text())
    assert index["Q2"]["error"].startswith("figure not drawn: eightpoint")
    drawn = {q for q, v in index.items() if "file" in v}
    assert drawn == set(index) - {"Q2"} and "Q4.1" in drawn, index  # Q4.1: its matcher called through map()
