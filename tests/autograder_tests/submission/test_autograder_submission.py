"""Reading submissions: which files answer which notebook, which code is kept, what is reported.

Each test builds the smallest submission that shows one behaviour, with nbformat's own factories.
Nothing here runs student code: parsing is ast only.
"""

from __future__ import annotations

import ast
import os
import zipfile
from pathlib import Path

import nbformat
import pytest
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

from autograder.submission.read import (
    SizeLimits,
    SubmissionError,
    load_submission,
    parse_notebook_cells,
    parse_notebook,
    parse_python,
)
from core.manifest import NOTEBOOKS, functions_of_notebook


def notebook_bytes(*cells) -> bytes:
    """A notebook of code cells (str) and markdown cells (("md", text))."""
    nb = new_notebook(cells=[new_markdown_cell(c[1]) if isinstance(c, tuple) else new_code_cell(c) for c in cells])
    return nbformat.writes(nb).encode()


def write_folder(root: Path, files: dict[str, bytes]) -> Path:
    for name, data in files.items():
        p = root / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data)
    return root


def write_zip(path: Path, files: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w") as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    return path


EIGHTPOINT_V1 = "import numpy as np\n\ndef eightpoint(pts1, pts2, M):\n    return 'first'\n"
EIGHTPOINT_V2 = "def eightpoint(pts1, pts2, M):\n    return 'second'\n"


# ---------------------------------------------------------------------------------------------
# cells and definitions


def test_later_definition_wins_and_is_last_in_the_units():
    nb = parse_notebook(notebook_bytes(EIGHTPOINT_V1, ("md", "# Q2"), "x = 1", EIGHTPOINT_V2),
                        stem="q2_eightpoint", filename="q2_eightpoint.ipynb")
    assert nb.redefined == {"eightpoint": 2}
    # Cell numbers count every cell, markdown included, as the student sees them.
    assert nb.definitions["eightpoint"] == "q2_eightpoint.ipynb, cell 4"
    last = [u for u in nb.units if "eightpoint" in u.defines][-1]
    assert "second" in last.source and last.origin.endswith("cell 4")
    assert any("defined 2 times" in d for d in map(str, nb.notes()))


def test_syntax_error_loses_only_its_cell():
    cells = ["def essentialMatrix(F, K1, K2):\n    return K2.T @ F @ K1\n",
             "def triangulate(C1, pts1, C2, pts2:\n    pass\n",
             "def findM2(F, pts1, pts2, intrinsics):\n    return None\n"]
    nb = parse_notebook_cells(cells, stem="q3_metric_reconstruction", filename="q3.ipynb")
    assert [p.cell for p in nb.syntax_errors] == [2]
    assert nb.syntax_errors[0].line == 1
    assert set(nb.definitions) == {"essentialMatrix", "findM2"}
    assert nb.missing == ("triangulate",)
    assert any("cell 2" in d and "syntax error" in d for d in map(str, nb.notes()))


def test_missing_function_is_reported():
    nb = parse_notebook_cells(["def essentialMatrix(F, K1, K2):\n    return F\n"],
                     stem="q3_metric_reconstruction", filename="q3_metric_reconstruction.ipynb")
    assert set(nb.missing) == set(functions_of_notebook("q3_metric_reconstruction")) - {"essentialMatrix"}
    assert any("findM2 is not defined" in d for d in map(str, nb.notes()))


def test_only_definitions_imports_and_simple_constants_are_kept():
    cell = (
        "import numpy as np\n"
        "from scipy import optimize as opt\n"
        "M = 640\n"
        "EPS = np.finfo(float).eps\n"
        "data = np.load('some_corresp.npz')\n"
        "F = eightpoint(data['pts1'], data['pts2'], M)\n"
        "print(F)\n"
        "THRESH = F[0, 0]\n"
        "skew = lambda v: np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])\n"
        "try:\n    import cv2\nexcept ImportError:\n    cv2 = None\n"
        "@np.vectorize\ndef sq(x):\n    return x * x\n"
        "class Camera:\n    pass\n"
    )
    nb = parse_notebook_cells([cell], stem="q2_eightpoint", filename="q2.ipynb")
    kept = set().union(*(u.defines for u in nb.units))
    assert kept == {"np", "opt", "M", "EPS", "skew", "cv2", "sq", "Camera"}
    # Every unit is valid Python on its own, and the decorator travels with its function.
    for u in nb.units:
        ast.parse(u.source)
    sq = next(u for u in nb.units if "sq" in u.defines)
    assert sq.source.startswith("@np.vectorize") and sq.line == 14


def test_magics_and_shell_lines_do_not_hide_definitions():
    cells = ["%matplotlib inline\n!pip install nothing\nimport numpy as np\n",
             "%%bash\necho not python\n",
             "%%time\ndef triangulate(C1, pts1, C2, pts2):\n    return 1\n",
             "np.linalg.svd?\ndef findM2(F, pts1, pts2, intrinsics):\n    !echo inside\n    return 2\n"]
    nb = parse_notebook_cells(cells, stem="q3_metric_reconstruction", filename="q3.ipynb")
    assert nb.syntax_errors == ()
    assert {"np", "triangulate", "findM2"} <= set(nb.definitions)
    tri = next(u for u in nb.units if "triangulate" in u.defines)
    assert tri.line == 2  # line numbers stay those of the cell


def test_python_file_split_in_percent_cells():
    text = ("# %% imports\nimport numpy as np\n"
            "# %% broken\ndef eightpoint(:\n"
            "# %% good\ndef eightpoint(pts1, pts2, M):\n    return 0\n")
    nb = parse_python(text.encode(), stem="q2_eightpoint", filename="q2_eightpoint.py")
    assert [p.cell for p in nb.syntax_errors] == [2]
    assert nb.syntax_errors[0].line == 4  # the file's own line number
    assert nb.definitions["eightpoint"].startswith("q2_eightpoint.py, line 6")


def test_future_import_is_marked_for_the_child():
    nb = parse_notebook_cells(["from __future__ import annotations\ndef f(x: Undefined) -> None:\n    pass\n"],
                     stem="q2_eightpoint", filename="q2.ipynb")
    assert nb.units[0].future == ("annotations",)


# ---------------------------------------------------------------------------------------------
# files, folders and archives


def test_invalid_json_notebook_is_unreadable_and_the_others_still_count(tmp_path):
    root = write_folder(tmp_path / "sub", {
        "q2_eightpoint.ipynb": b'{"cells": [ {"cell_type": "code", "source": "def eightpoint(',
        "q3_metric_reconstruction.ipynb": notebook_bytes("def findM2(F, pts1, pts2, intrinsics):\n    return 0\n"),
    })
    sub = load_submission(root)
    assert not sub.notebooks["q2_eightpoint"].readable
    assert "not valid JSON" in sub.notebooks["q2_eightpoint"].error
    assert "findM2" in sub.notebooks["q3_metric_reconstruction"].definitions
    assert any("q2_eightpoint.ipynb could not be read" in d for d in map(str, sub.notes()))
    assert sub.where_defined("eightpoint", "q2_eightpoint") is None
    assert [n.kind for n in sub.notes() if n.stem == "q2_eightpoint"] == ["unreadable"]


def test_zip_with_nested_folders_and_tolerant_names(tmp_path):
    good = notebook_bytes(EIGHTPOINT_V2)
    archive = write_zip(tmp_path / "submission.zip", {
        "andrew/hw4/Q2 Eightpoint (1).ipynb": good,
        "andrew/hw4/.ipynb_checkpoints/q2_eightpoint-checkpoint.ipynb": notebook_bytes(EIGHTPOINT_V1),
        "__MACOSX/andrew/hw4/._q2_eightpoint.ipynb": b"\x00\x05binary",
        "andrew/hw4/q3-metric.py": b"def triangulate(C1, pts1, C2, pts2):\n    return 3\n",
        "andrew/hw4/q20_notes.ipynb": good,
        "andrew/README.md": b"hello",
    })
    sub = load_submission(archive)
    assert sub.notebooks["q2_eightpoint"].filename == "andrew/hw4/Q2 Eightpoint (1).ipynb"
    assert "second" in sub.notebooks["q2_eightpoint"].units[-1].source
    assert "triangulate" in sub.notebooks["q3_metric_reconstruction"].definitions
    # Every file is read: q20_notes.ipynb too, but Q2's own file is the one whose eightpoint is used.
    assert "andrew/hw4/q20_notes.ipynb" in sub.files
    dup = next(n for n in sub.notes() if n.kind == "duplicate")
    assert dup.name == "eightpoint" and dup.file == "andrew/hw4/Q2 Eightpoint (1).ipynb"
    assert "names Q2" in str(dup) and "q20_notes.ipynb" in str(dup)
    assert not any(".ipynb_checkpoints" in f or "__MACOSX" in f for f in sub.files)
    assert set(sub.missing_notebooks) == set(NOTEBOOKS) - {"q2_eightpoint", "q3_metric_reconstruction"}


def test_exact_name_is_preferred_over_a_copy(tmp_path):
    root = write_folder(tmp_path / "sub", {
        "q2_eightpoint.ipynb": notebook_bytes(EIGHTPOINT_V2),
        "old/Copy of q2_eightpoint.ipynb": notebook_bytes(EIGHTPOINT_V1),
    })
    sub = load_submission(root)
    assert sub.notebooks["q2_eightpoint"].filename == "q2_eightpoint.ipynb"
    assert sub.functions["eightpoint"].filename == "q2_eightpoint.ipynb"
    dup = next(n for n in sub.notes() if n.kind == "duplicate")
    assert "old/Copy of q2_eightpoint.ipynb" in str(dup) and "closest to the kit's" in str(dup)
    last = [u for u in sub.units() if "eightpoint" in u.defines][-1]
    assert last.origin.startswith("q2_eightpoint.ipynb") and "second" in last.source


@pytest.mark.parametrize("evil", ["../evil.py", "/etc/q2_evil.py", "ok/../../q2_evil.py", "C:/q2_evil.py"])
def test_zip_slip_is_rejected(tmp_path, evil):
    archive = write_zip(tmp_path / "slip.zip", {"q2_eightpoint.ipynb": notebook_bytes(EIGHTPOINT_V2), evil: b"x = 1\n"})
    with pytest.raises(SubmissionError, match="rejected"):
        load_submission(archive)


def test_symlinks_in_a_folder_are_not_followed(tmp_path):
    outside = tmp_path / "outside.py"
    outside.write_text("def eightpoint(pts1, pts2, M):\n    return 'outside'\n")
    root = tmp_path / "sub"
    root.mkdir()
    os.symlink(outside, root / "q2_eightpoint.py")
    sub = load_submission(root)
    assert "q2_eightpoint" in sub.missing_notebooks


def test_size_limits(tmp_path):
    big = notebook_bytes("x = 1\n" + "# padding\n" * 200)
    root = write_folder(tmp_path / "sub", {"q2_eightpoint.ipynb": big,
                                           "q3_metric_reconstruction.py": b"def findM2(): pass\n"})
    sub = load_submission(root, limits=SizeLimits(max_file_bytes=len(big) - 1))
    assert not sub.notebooks["q2_eightpoint"].readable and "size limit" in sub.notebooks["q2_eightpoint"].error
    assert "findM2" in sub.notebooks["q3_metric_reconstruction"].definitions
    with pytest.raises(SubmissionError, match="bytes"):
        load_submission(root, limits=SizeLimits(max_total_bytes=len(big)))


def test_not_a_submission(tmp_path):
    (tmp_path / "notes.txt").write_text("hi")
    with pytest.raises(SubmissionError, match="path"):
        load_submission(tmp_path / "notes.txt")


def test_units_borrow_from_other_notebooks_but_own_definitions_win(tmp_path):
    root = write_folder(tmp_path / "sub", {
        "q2_eightpoint.ipynb": notebook_bytes("def helper():\n    return 'q2'\n"),
        "q3_metric_reconstruction.ipynb": notebook_bytes(
            "def helper():\n    return 'q3'\n", "def eightpoint(a, b, c):\n    return 'in q3'\n",
            "def triangulate(C1, pts1, C2, pts2):\n    return 'q3'\n"),
        "q4_temple_3d.ipynb": notebook_bytes("def triangulate(C1, pts1, C2, pts2):\n    return 'q4'\n"),
    })
    sub = load_submission(root)
    units = sub.units()
    # q2's helper first, then q3's (manifest order); each notebook's own functions again at the end.
    assert [u.origin.split(",")[0] for u in units if "helper" in u.defines] == [
        "q2_eightpoint.ipynb", "q3_metric_reconstruction.ipynb"]
    assert [u for u in units if "triangulate" in u.defines][-1].origin.startswith("q3_metric_reconstruction")
    assert sub.where_defined("eightpoint", "q2_eightpoint").startswith("q3_metric_reconstruction.ipynb")
    borrowed = [n for n in sub.notes() if n.kind == "borrowed"]
    assert [(n.name, n.stem) for n in borrowed] == [("eightpoint", "q2_eightpoint")]
    assert str(borrowed[0]) == "eightpoint was found in q3_metric_reconstruction.ipynb, cell 2 and is used from there."


def test_units_leave_out_the_notebooks_self_checks_runs_and_links():
    cells = ["from starter.notebook_import import from_notebook, try_run\n"
             "from starter.checks import check_findM2\nimport numpy as np\n",
             "eightpoint = from_notebook('q2_eightpoint.ipynb', 'eightpoint')\n",
             "def findM2(F, pts1, pts2, intrinsics):\n    return 1\n",
             "M1 = np.eye(3)\nreport = check_findM2(findM2)\nF = try_run(eightpoint, M1, M1, 640)\n"
             "best = findM2(M1, M1, M1, M1)\nLIMIT = np.sqrt(2)\n"]
    nb = parse_notebook_cells(cells, stem="q3_metric_reconstruction", filename="q3.ipynb")
    kept = set().union(*(u.defines for u in nb.units))
    assert kept == {"from_notebook", "try_run", "check_findM2", "np", "findM2", "M1", "LIMIT"}
    # A function fetched with from_notebook is not "found" in this notebook: the grader loads q2 itself.
    assert "eightpoint" not in nb.definitions


def test_a_renamed_notebook_is_recognised_by_its_metadata(tmp_path):
    nb = nbformat.v4.new_notebook(cells=[new_code_cell(EIGHTPOINT_V2)])
    nb.metadata["hw4_kit"] = {"stem": "q2_eightpoint", "variant": "student"}
    root = write_folder(tmp_path / "sub", {"Untitled (1).ipynb": nbformat.writes(nb).encode()})
    sub = load_submission(root)
    assert sub.notebooks["q2_eightpoint"].filename == "Untitled (1).ipynb"


# ---------------------------------------------------------------------------------------------
# any hand-in layout: modules, duplicates, helper, signatures


def test_py_files_become_modules_named_as_on_the_students_machine(tmp_path):
    root = write_folder(tmp_path / "sub", {
        "andrew_hw4/code/q3_1_essential_matrix.py": b"def essentialMatrix(F, K1, K2):\n    return F\n",
        "andrew_hw4/code/q3_2_triangulate.py": (b"from q3_1_essential_matrix import essentialMatrix\n"
                                                b"from helper import camera2\n"
                                                b"def triangulate(C1, pts1, C2, pts2):\n    return 1\n"
                                                b"if __name__ == '__main__':\n    triangulate(1, 2, 3, 4)\n"),
        "andrew_hw4/code/HW4 scratch.py": b"def findM2(F, pts1, pts2, intrinsics, filename='q3_3.npz'):\n    pass\n",
    })
    sub = load_submission(root)
    code = "andrew_hw4/code/"
    assert sub.modules["q3_1_essential_matrix"] == code + "q3_1_essential_matrix.py"
    assert sub.modules["andrew_hw4.code.q3_2_triangulate"] == code + "q3_2_triangulate.py"
    assert "code.q3_2_triangulate" not in sub.modules  # 'code' is the standard library's
    private = [m for m, f in sub.modules.items() if f == code + "HW4 scratch.py"]
    assert private and private[0].startswith("_hw4_file_")
    # helper is the kit's given helpers, and the note says who imported it.
    assert sub.modules["helper"] == "the kit's given helpers (starter)"
    given = [n for n in sub.notes() if n.kind == "given_helper"]
    assert given and given[0].file == code + "q3_2_triangulate.py"
    units = sub.units()
    bodies = {u.module for u in units if u.module}
    assert {"q3_1_essential_matrix", "helper", "andrew_hw4", "andrew_hw4.code"} <= bodies
    assert all("__name__" not in u.source for u in units)
    # The grader's namespace gets each homework function from its module.
    assert any(u.source == "from q3_2_triangulate import triangulate" and u.module is None for u in units)
    assert [u.to_job().get("module") for u in units if u.module == "helper"] == ["helper"]
    # The parameters as written: another year's findM2 is recognisable.
    sig = sub.signature("findM2")
    assert sig.positional == ("F", "pts1", "pts2", "intrinsics", "filename") and sig.required[-1] == "intrinsics"
    assert sub.functions["findM2"].params == ("F", "pts1", "pts2", "intrinsics", "filename")
    assert str(sig) == "(F, pts1, pts2, intrinsics, filename=...)"


def test_a_shipped_helper_is_the_students_own(tmp_path):
    root = write_folder(tmp_path / "sub", {
        "submission.py": b"import helper\ndef eightpoint(pts1, pts2, M):\n    return helper.refineF(0, 1, 2)\n",
        "helper.py": b"def refineF(F, pts1, pts2):\n    return 'mine'\n",
    })
    sub = load_submission(root)
    assert sub.modules["helper"] == "helper.py"
    assert not any(n.kind == "given_helper" for n in sub.notes())
    assert not any(u.module == "helpers" for u in sub.units())  # nobody imports 'helpers'


def test_fall_2023s_util_is_the_kits_given_helpers(tmp_path):
    """Fall 2023 gave the course's helpers as util.py: imported and not shipped, util is the kit's,
    with the names that file had (refineF, _singularize, camera2, displayEpipolarF, epipolarMatchGUI)."""
    import types

    from autograder.submission.read import GIVEN_HELPERS_ORIGIN

    root = write_folder(tmp_path / "sub", {
        "submission.py": b"import util\ndef eightpoint(pts1, pts2, M):\n    return util._singularize(util.refineF)\n",
    })
    sub = load_submission(root)
    assert sub.modules["util"] == GIVEN_HELPERS_ORIGIN
    assert [n.name for n in sub.notes() if n.kind == "given_helper"] == ["util"]
    body = next(u for u in sub.units() if u.module == "util")
    util = types.ModuleType("util")
    exec(compile(body.source, "<util>", "exec"), util.__dict__)  # noqa: S102 - the kit's own source
    for name in ("refineF", "_singularize", "camera2", "displayEpipolarF", "epipolarMatchGUI", "rodrigues"):
        assert callable(getattr(util, name)), name
    # A util.py of the student's own stays theirs.
    mine = load_submission(write_folder(tmp_path / "mine", {"submission.py": b"import util\n",
                                                            "util.py": b"def refineF(F, a, b):\n    return F\n"}))
    assert mine.modules["util"] == "util.py"


def test_duplicates_prefer_the_file_of_the_question_else_the_last(tmp_path):
    root = write_folder(tmp_path / "sub", {
        "a_scratch.py": b"def triangulate(C1, pts1, C2, pts2):\n    return 'scratch'\n"
                        b"def essentialMatrix(F, K1, K2):\n    return 'a'\n",
        "q3_2_triangulate.py": b"def triangulate(C1, pts1, C2, pts2):\n    return 'q3.2'\n",
        "z_more.py": b"def essentialMatrix(F, K1, K2):\n    return 'z'\n",
    })
    sub = load_submission(root)
    assert sub.functions["triangulate"].filename == "q3_2_triangulate.py"
    assert "names Q3.2" in sub.functions["triangulate"].reason
    # No file's name matches Q3.1: the last one in reading (path) order.
    assert sub.functions["essentialMatrix"].filename == "z_more.py"
    assert "last one defined" in sub.functions["essentialMatrix"].reason
    notes = {n.name: str(n) for n in sub.notes() if n.kind == "duplicate"}
    assert "a_scratch.py, line 1" in notes["triangulate"] and "z_more.py is used" in notes["essentialMatrix"]
    last = [u for u in sub.units() if "essentialMatrix" in u.defines and u.module is None][-1]
    assert last.source == "from z_more import essentialMatrix"


def test_a_module_relying_on_the_shared_namespace_is_linked(tmp_path):
    root = write_folder(tmp_path / "sub", {
        "q3_metric_reconstruction.py": b"def triangulate(C1, pts1, C2, pts2):\n    return 1\n",
        "q4_temple_3d.py": b"def compute3D_pts(im1, im2, F, x1, y1, C1, C2):\n    return triangulate(C1, 0, C2, 0)\n",
    })
    sub = load_submission(root)
    link = sub.units()[-1]
    assert "q4_temple_3d" in link.source and "triangulate" in link.source and link.module is None
    ast.parse(link.source)


def test_one_notebook_with_everything_answers_every_notebook(tmp_path):
    root = write_folder(tmp_path / "sub", {"my hw4.ipynb": notebook_bytes(
        EIGHTPOINT_V1, "def findM2(F, pts1, pts2, K1, K2):\n    return 0\n", "F = eightpoint(1, 2, 3)\n")})
    sub = load_submission(root)
    assert sub.notebooks["q2_eightpoint"].filename == "my hw4.ipynb"
    assert sub.notebooks["q3_metric_reconstruction"].filename == "my hw4.ipynb"
    assert "q2_eightpoint" not in sub.missing_notebooks and "q4_temple_3d" in sub.missing_notebooks
    kinds = {(n.kind, n.name) for n in sub.notes()}
    assert ("missing", "triangulate") in kinds and not any(k == "borrowed" for k, _ in kinds)
    assert not any("eightpoint(1, 2, 3)" in u.source for u in sub.units())
