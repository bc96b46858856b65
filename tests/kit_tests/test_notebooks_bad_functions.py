"""Every notebook runs to its end under nbconvert (no ``--allow-errors``) whatever the student's
functions do: the kit's own cells are contained like the student's (``kit_cell`` of the setup
cell, ``try_run``, the self-checks and their figures), so a bad function prints lines, never a
traceback, and never stops the notebook.

Each student notebook gets its stubs replaced by functions of one kind of bug, in all notebooks
at once (the later notebooks load the earlier ones' functions): "malformed" (wrong shapes, and
arrays where a number is expected: Q6's 8 keypoints with an array of errors, Q5's o1 an array),
"nan" (the right shapes, every number NaN) and "raise" (an exception that is not a stub's).
"""

from __future__ import annotations

import re
import shutil
import textwrap

import nbformat
import pytest

from core.manifest import NOTEBOOKS, functions_of_notebook
from kit import notebooks as nbk

pytestmark = pytest.mark.slow

# function -> the body of a function of that kind of bug (its arguments as the handout names them)
MALFORMED = {
    "eightpoint": "return np.zeros((2, 2))",
    "essentialMatrix": "return np.ones(4)",
    "triangulate": "return np.zeros((len(pts1), 3)), np.zeros(len(pts1))",      # err an array
    "findM2": "return np.zeros((3, 3)), np.zeros(2), np.zeros((5, 3))",
    "epipolarCorrespondence": "return np.array([1.0, 2.0]), np.array([3.0, 4.0])",
    "compute3D_pts": "return np.zeros((5, 2))",
    "rodriguesResidual": "return np.zeros(3)",
    "bundleAdjustment": "return np.hstack([np.eye(3), np.ones((3, 1))]), np.ones((len(p1), 3)), np.ones(4), np.ones(4)",
    "MultiviewReconstruction": "return np.zeros((8, 3)), np.zeros(8)",
    "plot_3d_keypoint_video": "return 'not a figure'",
}
NAN = {
    "eightpoint": "return np.full((3, 3), np.nan)",
    "essentialMatrix": "return np.full((3, 3), np.nan)",
    "triangulate": "return np.full((len(pts1), 3), np.nan), np.nan",
    "findM2": "return np.full((3, 4), np.nan), np.full((3, 4), np.nan), np.full((len(pts1), 3), np.nan)",
    "epipolarCorrespondence": "return np.nan, np.nan",
    "compute3D_pts": "return np.full((len(x1), 3), np.nan), np.full((len(x1), 2), np.nan)",
    "rodriguesResidual": "return np.full(4 * len(p1), np.nan)",
    "bundleAdjustment": "return np.full((3, 4), np.nan), np.full((len(p1), 3), np.nan), np.nan, np.nan",
    "MultiviewReconstruction": "return np.full((len(pts1), 3), np.nan), np.nan",
    "plot_3d_keypoint_video": "return None",
}
RAISE = {name: "raise ValueError('a bug of the student, not a stub')" for name in MALFORMED}
KINDS = {"malformed": MALFORMED, "nan": NAN, "raise": RAISE}


def _with_bugs(stem: str, bodies: dict) -> nbformat.NotebookNode:
    nb = nbformat.read(nbk.output_path(stem, "student"), as_version=4)
    for cell in nb.cells:
        for name in functions_of_notebook(stem):
            if cell.cell_type == "code" and cell.source.startswith(f"def {name}("):
                body = textwrap.indent(f"import numpy as np\n{bodies[name]}", "    ")
                assert nbk.NBGRADER_STUB.splitlines()[-1] in cell.source, name
                cell.source = cell.source.replace("    " + nbk.NBGRADER_STUB.replace("\n", "\n    "), body)
    return nb


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_every_notebook_runs_to_the_end_whatever_the_functions_do(kind, tmp_path, homework_data, monkeypatch):
    from nbconvert.preprocessors import ExecutePreprocessor

    monkeypatch.setenv("HW4_DATA", str(homework_data))
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    for stem in NOTEBOOKS:
        if not functions_of_notebook(stem):
            continue
        # The earlier notebooks' functions are the key's, so that every cell of this one is reached.
        folder = tmp_path / stem
        folder.mkdir()
        for other in NOTEBOOKS:
            shutil.copy(nbk.output_path(other, "key"), folder / f"{other}.ipynb")
        nb = _with_bugs(stem, KINDS[kind])
        # allow_errors False, as nbconvert --execute without --allow-errors: a cell that raises fails here
        ExecutePreprocessor(timeout=120, kernel_name="python3", allow_errors=False).preprocess(
            nb, {"metadata": {"path": str(folder)}})
        outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
        assert not [o for o in outputs if o.output_type == "error"], stem
        text = "".join(o.get("text", "") for o in outputs if o.output_type == "stream")
        assert "Traceback (most recent call last)" not in text, (stem, text[-3000:])
        if kind == "raise":
            assert "a bug of the student" in text, stem   # said in one line, not hidden


def test_a_wrong_findM2_is_named_under_q42s_cloud(tmp_path, homework_data, monkeypatch):
    """Q4.2's cloud uses C2 from the student's findM2 (Q3.3): a wrong candidate there (t of the
    wrong sign, the points behind the cameras) is named under the cloud, where
    check_compute3D_pts (given the true cameras) passes."""
    from nbconvert.preprocessors import ExecutePreprocessor

    monkeypatch.setenv("HW4_DATA", str(homework_data))
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    for stem in NOTEBOOKS:
        shutil.copy(nbk.output_path(stem, "key"), tmp_path / f"{stem}.ipynb")
    q3 = nbformat.read(tmp_path / "q3_metric_reconstruction.ipynb", as_version=4)
    q3.cells.append(nbformat.v4.new_code_cell(
        "def findM2(F, pts1, pts2, K1, K2, right=findM2):\n"
        "    M2, C2, w = right(F, pts1, pts2, K1, K2)\n"
        "    wrong = np.hstack([M2[:, :3], -M2[:, 3:]])\n"
        "    return wrong, K2 @ wrong, w"))
    nbformat.write(q3, tmp_path / "q3_metric_reconstruction.ipynb")
    nb = nbformat.read(tmp_path / "q4_temple_3d.ipynb", as_version=4)
    ExecutePreprocessor(timeout=120, kernel_name="python3", allow_errors=False).preprocess(
        nb, {"metadata": {"path": str(tmp_path)}})
    text = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
                   if o.output_type == "stream")
    assert re.search(r"check compute3D_pts: (\d+)/\1 passed", text), text[-2000:]   # the self-check cannot tell
    assert "C2 comes from your findM2 (Q3.3), which likely chose the wrong candidate" in text, text[-2000:]
