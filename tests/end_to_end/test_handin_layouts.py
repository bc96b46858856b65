"""Hand-ins in every layout graded end to end: each scores what its name says (tests/support/handin_layouts).

The slow test grades the whole corpus through the real CLI (``python -m autograder grade``) in the
sandbox; the others check, without any sandbox, which file each function is taken from.
"""

from __future__ import annotations

import ast
import csv
import json
import subprocess
import sys

import handin_layouts
import pytest

from autograder.channels.batch import submission_name
from autograder.inputs.config import quick_config
from autograder.submission.read import load_submission
from core.manifest import QUESTIONS

AUTOGRADED = [q for q in QUESTIONS if q.functions]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    root = tmp_path_factory.mktemp("layouts")
    return {name: handin_layouts.build(name, root) for name in handin_layouts.CASES}


@pytest.mark.parametrize("name", list(handin_layouts.CASES))
def test_every_homework_function_is_found(built, name):
    sub = load_submission(built[name])
    assert set(sub.functions) == {f for q in AUTOGRADED for f in q.functions}
    assert sub.notebooks, "grade.py needs at least one notebook's file to grade"


def test_per_part_files_take_each_function_from_the_file_named_after_its_question(built):
    sub = load_submission(built["layout_per_part_files_full_marks"])
    code = "HW4 final (2)/andrew_hw4/code/"
    assert sub.functions["eightpoint"].filename == code + "q2_1_eightpoint.py"
    assert sub.functions["eightpoint"].module == "q2_1_eightpoint"
    assert sub.modules["helper"] == "the kit's given helpers (starter)"
    assert sub.modules["andrew_hw4.code.q3_1_essential_matrix"] == code + "q3_1_essential_matrix.py"
    dup = [n for n in sub.notes() if n.kind == "duplicate"]
    assert [n.name for n in dup] == ["eightpoint"]
    assert "names Q2" in str(dup[0]) and "q4_1_epipolar_correspondence.py, line" in str(dup[0])
    assert not any(n.kind in ("borrowed", "missing", "not_used") for n in sub.notes())


def test_submission_py_hand_in_runs_no_script_code(built):
    sub = load_submission(built["layout_submission_py_full_marks"])
    assert sub.modules["helper"] == "helper.py"  # the student's own helper, not the kit's
    assert sub.functions["findM2"].filename == "findM2.py"
    for u in (u for pf in sub.files.values() for u in pf.units):
        for node in ast.parse(u.source).body:  # what runs at import: definitions, never the script part
            assert not isinstance(node, ast.If | ast.Expr | ast.For | ast.With), (u.origin, u.source[:80])
            if isinstance(node, ast.Assign):
                assert "np.load(" not in u.source and "findM2(" not in u.source


OTHER_YEAR_RANSACF = {"layout_submission_py_full_marks": "submission.py",
                      "layout_submission_py_q2_transposed_loses_q2": "submission.py",
                      "layout_per_part_files_full_marks": "HW4 final (2)/andrew_hw4/code/q5_1_ransac.py"}
RANSACF_NOTE = "ransacF(pts1, pts2, M, nIters=..., tol=...) was recognised as another course year's signature"


@pytest.mark.parametrize("name", list(handin_layouts.CASES))
def test_another_years_ransacF_is_noted_once(built, name):
    notes = [str(n) for n in load_submission(built[name]).notes() if n.kind == "other_year"]
    if name not in OTHER_YEAR_RANSACF:
        assert notes == []
        return
    assert len(notes) == 1, notes
    assert notes[0].startswith(OTHER_YEAR_RANSACF[name] + ": your own " + RANSACF_NOTE), notes[0]
    assert "does not grade it" in notes[0]


def test_ransacF_signatures_are_told_apart():
    from autograder.submission.layout import Signature, another_years_ransacF

    assert another_years_ransacF(Signature(("pts1", "pts2", "M", "nIters", "tol"), 2))
    assert another_years_ransacF(Signature(("pts1", "pts2", "M")))
    assert not another_years_ransacF(Signature(("pts1", "pts2", "M", "eightpoint", "nIters", "tol", "rng",
                                                "confidence"), 4))           # the kit's own
    assert not another_years_ransacF(Signature(("pts1", "pts2", "M", "nIters", "tol"), 0))   # five required
    assert not another_years_ransacF(Signature(("pts1", "pts2", "M"), 0, kwonly=("eightpoint_fn",)))
    assert not another_years_ransacF(Signature(("pts1", "pts2"), 0, varargs="args"))
    assert not another_years_ransacF(None)


@pytest.mark.slow
def test_each_layout_gets_the_grade_its_name_says(built, tmp_path):
    config = quick_config()
    cfg = tmp_path / "grader.json"
    cfg.write_text(json.dumps({
        "temples": [{"width": t.width, "height": t.height, "noise_px": t.noise_px} for t in config.temples],
        "match_points": config.match_points, "ba_points": config.ba_points, "car_times": config.car_times,
        "time_scale": config.time_scale, "load_timeout": config.load_timeout}))
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "autograder", "grade", *map(str, built.values()), "--out", str(out),
                           "--config", str(cfg), "--jobs", "2", "--quiet", "--no-pictures"],
                          capture_output=True, text=True, timeout=3000, check=False)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    with open(out / "grades.csv", newline="") as fh:
        rows = {r["student_id"]: r for r in csv.DictReader(fh)}
    for name, path in built.items():
        row = rows[submission_name(path)]
        loses = handin_layouts.CASES[name].loses
        for q in AUTOGRADED:
            score = float(row[q.id])
            if q.id in loses:
                assert score < q.points, f"{name}: {q.id} should lose points, got {score}/{q.points}"
            else:
                assert score == pytest.approx(q.points), f"{name}: {q.id} got {score}/{q.points}"
        output = json.loads((out / submission_name(path) / "results.json").read_text())["output"]
        assert output.count(RANSACF_NOTE) == (name in OTHER_YEAR_RANSACF), (name, output)
