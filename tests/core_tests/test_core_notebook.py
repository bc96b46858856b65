"""The one notebook reader (core.notebook): cells, magics, problems as data, the kept statements,
and the stem from metadata so that renamed copies are recognised everywhere."""

from __future__ import annotations

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

from core.notebook import (
    code_cells,
    definitions,
    find_notebook,
    notebook_stem,
    parse_cells,
    python_text,
)
from starter.notebook_import import from_notebook


def _nb(*cells, stem=None) -> nbformat.NotebookNode:
    nb = new_notebook(cells=[new_markdown_cell(c[1]) if isinstance(c, tuple) else new_code_cell(c) for c in cells])
    if stem:
        nb.metadata["hw4_kit"] = {"stem": stem, "variant": "student"}
    return nb


def test_cells_are_numbered_as_the_student_counts_them():
    cells = code_cells(nbformat.writes(_nb(("md", "# Q2"), "x = 1", ("md", "text"), "y = 2")))
    assert [(c.number, c.source) for c in cells] == [(2, "x = 1"), (4, "y = 2")]


def test_magics_become_pass_and_other_languages_are_left_out():
    assert python_text("%%bash\necho hi\n") is None
    text = python_text("%matplotlib inline\nimport numpy as np\nnp.linalg.svd?\nfiles = !ls\n")
    assert text.splitlines() == ["pass", "import numpy as np", "pass", "pass"]
    assert python_text("x = 1  # 100%\n") == "x = 1  # 100%\n"  # valid Python is left as it is


def test_problems_are_data_and_other_cells_still_count():
    parsed, problems = parse_cells(["def f(:\n    pass\n", "def g():\n    return 1\n"])
    assert [(p.cell, p.line) for p in problems] == [(1, 1)] and "syntax error" in problems[0].message
    assert [d.defines for d in definitions(parsed)] == [("g",)]


def test_one_rule_set_with_the_two_real_differences():
    cells = ["import numpy as np\nfrom starter.notebook_import import from_notebook, try_run",
             "eightpoint = from_notebook('q2_eightpoint.ipynb', 'eightpoint')",
             "M = 640\nd = np.load('x.npz')\nF = try_run(eightpoint, 1, 2, M)\nreport = check_x(eightpoint)",
             "try:\n    import cv2\nexcept ImportError:\n    cv2 = None"]
    parsed, _ = parse_cells(cells)

    def kept(**kw):
        return [n for d in definitions(parsed, homework={"eightpoint"}, **kw) for n in d.defines]

    assert kept() == ["np", "from_notebook", "try_run", "M", "cv2"]               # the grader
    assert kept(constants=False, links=True) == ["np", "from_notebook", "try_run", "eightpoint", "cv2"]


def test_stem_from_metadata_finds_renamed_copies(tmp_path):
    nb = _nb("def double(x):\n    return 2 * x\n", stem="q2_eightpoint")
    assert notebook_stem(nbformat.writes(nb)) == "q2_eightpoint"
    assert notebook_stem(b"not json") is None and notebook_stem(nbformat.writes(_nb("x = 1"))) is None
    nbformat.write(nb, tmp_path / "Copy of q2_eightpoint.ipynb")
    assert find_notebook(tmp_path, "q2_eightpoint").name == "Copy of q2_eightpoint.ipynb"
    assert find_notebook(tmp_path, "q3_metric_reconstruction") is None
    # A later notebook's from_notebook finds the renamed copy.
    assert from_notebook("q2_eightpoint.ipynb", "double", folder=tmp_path)(4) == 8
    nbformat.write(_nb("def double(x):\n    return 0\n"), tmp_path / "q2_eightpoint.ipynb")
    assert find_notebook(tmp_path, "q2_eightpoint").name == "q2_eightpoint.ipynb"  # the exact name wins


def test_code_zip_takes_a_renamed_copy_under_its_own_name(tmp_path):
    import zipfile

    from handin.code_zip import build_code_zip as build_bundle

    nbformat.write(_nb("def eightpoint(pts1, pts2, M):\n    return 1\n", stem="q2_eightpoint"),
                   tmp_path / "q2_eightpoint (1).ipynb")
    report = build_bundle(tmp_path, tmp_path / "out" / "code.zip")
    assert "q2_eightpoint" not in report.missing_notebooks and "q2_eightpoint" not in report.missing_functions
    assert "q2_eightpoint.ipynb" in zipfile.ZipFile(report.zip_path).namelist()
