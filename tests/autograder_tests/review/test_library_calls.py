"""Library calls that do the homework's work: found in the code through aliases, listed for the staff only."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import nbformat
import pytest

from autograder.inputs import config as grader_config
from autograder.inputs.config import configuration, load_config, quick_config
from autograder.channels.gradebook import BatchRecord, write_summary
from autograder.feedback.results import QuestionResult, SubmissionResult, TestResult
from autograder.review.__main__ import main
from autograder.review.library_calls import find_in_class, find_library_calls
from core.paths import KIT_ROOT

KEY = KIT_ROOT / "notebooks" / "key"

# cells a student adds to the key's notebooks: OpenCV does the eight-point algorithm and triangulation
IMPORTS = {"q2_eightpoint": "import cv2 as cv\nfrom cv2 import findFundamentalMat as find_F\n",
           "q3_metric_reconstruction": "import cv2 as cv\n"}
EIGHTPOINT = ("def eightpoint(pts1, pts2, M):\n"
              "    F, mask = find_F(pts1, pts2, cv.FM_8POINT)\n"
              "    return F / F[2, 2]\n")
TRIANGULATE = ("def triangulate(C1, pts1, C2, pts2):\n"
               "    X = cv.triangulatePoints(C1, C2, pts1.T.astype(float), pts2.T.astype(float))\n"
               "    w = (X[:3] / X[3]).T\n"
               "    return w, 0.0\n")


def _with_opencv(folder: Path) -> Path:
    """The answer key's notebooks, with eightpoint and triangulate redone with OpenCV in cells of their own
    (the imports in a cell before, as a student's notebook has them)."""
    shutil.copytree(KEY, folder)
    for stem, code in (("q2_eightpoint", EIGHTPOINT), ("q3_metric_reconstruction", TRIANGULATE)):
        nb = nbformat.read(folder / f"{stem}.ipynb", as_version=4)
        nb.cells += [nbformat.v4.new_code_cell(IMPORTS[stem]), nbformat.v4.new_code_cell(code)]
        nbformat.write(nb, folder / f"{stem}.ipynb")
    return folder


def test_opencv_calls_are_found_through_aliases_and_the_key_has_none(tmp_path):
    calls, notes = find_library_calls(_with_opencv(tmp_path / "sub"))
    assert notes == []
    got = {(c.name, c.kind, c.function, c.code) for c in calls}
    assert got == {
        ("cv2.findFundamentalMat", "call", "eightpoint", "find_F(pts1, pts2, cv.FM_8POINT)"),
        ("cv2.triangulatePoints", "call", "triangulate",
         "cv.triangulatePoints(C1, C2, pts1.T.astype(float), pts2.T.astype(float))"),
    }
    where = {c.name: c.where for c in calls}
    assert where["cv2.triangulatePoints"].startswith("q3_metric_reconstruction.ipynb, cell ")
    assert where["cv2.triangulatePoints"].endswith(", line 2")
    assert find_library_calls(KEY) == ([], [])


def test_other_spellings_of_a_listed_name(tmp_path):
    sub = tmp_path / "s.py"
    sub.write_text("from scipy.spatial.transform import Rotation as R\nfrom cv2 import *\n"
                   "import skimage.measure\nfrom skimage.transform import FundamentalMatrixTransform\n"
                   "from cv2 import recoverPose\nimport cv2\n\n"
                   "def rodriguesResidual(K1, M1, p1, K2, p2, x):\n"
                   "    R2 = R.from_rotvec(x[-6:-3]).as_matrix()\n"
                   "    E = findEssentialMat(p1, p2, K1)\n"
                   "    m, inl = skimage.measure.ransac((p1, p2), FundamentalMatrixTransform, 8, 1.0)\n"
                   "    return cv2.imread('x.png')\n")
    found = {(c.name, c.kind) for c in find_library_calls(sub)[0]}
    assert found == {("scipy.spatial.transform.Rotation", "call"), ("cv2.findEssentialMat", "call"),
                     ("skimage.measure.ransac", "call"), ("skimage.transform.FundamentalMatrixTransform", "reference"),
                     ("cv2.recoverPose", "import")}  # cv2.imread is not on the list, recoverPose imported unused


def _graded(tmp_path: Path, submissions: dict[str, Path]) -> Path:
    """A graded folder as the batch leaves it: results.json and grading.json (which names the code) per student."""
    graded = tmp_path / "graded"
    for name, path in submissions.items():
        r = SubmissionResult((QuestionResult.of("Q2", [TestResult("F is rank 2", 10, 10)]),), student_id=name)
        (graded / name).mkdir(parents=True)
        r.write_gradescope(graded / name / "results.json")
        (graded / name / "grading.json").write_text(json.dumps({"student_id": name, "path": str(path)}))
    return graded


def test_class_report_lists_the_calls_for_the_staff(tmp_path):
    graded = _graded(tmp_path, {"key": KEY, "cv_student": _with_opencv(tmp_path / "cv"),
                                "moved": tmp_path / "gone"})
    assert main(["report", str(graded), "--out", str(tmp_path / "report")]) == 0
    rows = list(csv.DictReader((tmp_path / "report" / "library_calls.csv").open()))
    assert {(r["student"], r["library_function"], r["in_function"]) for r in rows} == {
        ("cv_student", "cv2.findFundamentalMat", "eightpoint"), ("cv_student", "cv2.triangulatePoints", "triangulate")}
    assert any(r["code"] == "find_F(pts1, pts2, cv.FM_8POINT)" for r in rows)
    page = (tmp_path / "report" / "report.html").read_text()
    section = page[page.index("id='library-calls'"):]
    assert "cv2.triangulatePoints" in section and "1 of 3 submissions" in section and "moved" in section
    assert "no points were taken" in section
    # the student's own results are untouched: nothing of the list reaches what the student sees
    assert "cv2" not in (graded / "cv_student" / "results.json").read_text()


def test_an_instructor_list_replaces_the_default(tmp_path):
    config = tmp_path / "grader.json"
    config.write_text(json.dumps({**quick_config().to_dict(), "library_calls": ["cv2.triangulatePoints"]}))
    graded = _graded(tmp_path, {"cv_student": _with_opencv(tmp_path / "cv")})
    assert main(["report", str(graded), "--out", str(tmp_path / "r"), "--config", str(config)]) == 0
    rows = list(csv.DictReader((tmp_path / "r" / "library_calls.csv").open()))
    assert [r["library_function"] for r in rows] == ["cv2.triangulatePoints"]
    # the list changes no grade: the configuration (and so resuming a graded folder) is the same
    plain, listed = quick_config(), load_config(config)
    assert listed.library_calls == ("cv2.triangulatePoints",)
    tests = grader_config.tests_fingerprint()
    assert configuration(plain, tests=tests)["key"] == configuration(listed, tests=tests)["key"]


@pytest.mark.parametrize("content, message", [
    ({"library_call": ["cv2.triangulatePoints"]}, "unknown key 'library_call' (did you mean 'library_calls'?)"),
    ({"library_calls": "cv2.triangulatePoints"}, "library_calls: expected a list of dotted names"),
    ({"library_calls": ["triangulatePoints"]}, "library_calls: expected a list of dotted names"),
])
def test_a_wrong_config_is_refused_clearly(tmp_path, capsys, content, message):
    config = tmp_path / "grader.json"
    config.write_text(json.dumps(content))
    with pytest.raises(ValueError) as err:
        load_config(config)
    assert message in str(err.value)
    graded = _graded(tmp_path, {"key": KEY})
    assert main(["report", str(graded), "--out", str(tmp_path / "r"), "--config", str(config)]) == 2
    assert message in capsys.readouterr().err


def test_grade_summary_lists_the_calls(tmp_path):
    cv = _with_opencv(tmp_path / "cv")
    records = [BatchRecord(n, p, tmp_path / n, 50.0, {"Q2": 10.0}, None, False, 1.0) for n, p in
               (("key", KEY), ("cv_student", cv))]
    calls = find_in_class([(r.name, r.path) for r in records], quick_config().library_names())
    text = write_summary(tmp_path / "summary.md", records, configuration(quick_config(), tests={"digest": "t"}),
                         library_calls=calls).read_text()
    section = text[text.index("## Library calls to look at"):]
    assert "1 of 2 submissions" in section and "no points were taken" in section
    assert "- cv_student: `cv2.findFundamentalMat` (eightpoint / RANSAC), call in `eightpoint`: " \
           "`find_F(pts1, pts2, cv.FM_8POINT)`" in section
    assert "- key" not in section
