"""The notebooks built from notebooks/src and solutions/, the notebook helpers, and the student release.

Fast tests read the committed notebooks and the builder's output; the ``slow`` ones execute
notebooks headless with nbclient on the kit's default data (generated into a temporary folder
when data/ is not there yet).
"""

from __future__ import annotations

import ast
import json
import os
import re
import shutil
from pathlib import Path

import nbformat
import numpy as np
import pytest
import tomllib

import solutions
from kit import notebooks as nbk
from core.manifest import NOTEBOOKS, QUESTION_HEADING, QUESTIONS, functions_of_notebook
from core.paths import KIT_ROOT
from core.shipping import NEVER_TO_STUDENTS, STUDENT_PACKAGES
from kit.release import RELEASE_TOP, leaks, reference_bodies, release_packages, write_release
from scenes.cameras import project
from starter.notebook_import import from_notebook, notebook_definitions, try_run

ALL_FUNCTIONS = [f for q in QUESTIONS for f in q.functions]


def committed(stem: str, variant: str) -> nbformat.NotebookNode:
    path = nbk.output_path(stem, variant)
    if not path.exists():
        pytest.fail(f"{path} is missing: run python -m kit notebooks")
    return nbformat.read(path, as_version=4)


def code_cells(nb) -> list[str]:
    return [c.source for c in nb.cells if c.cell_type == "code"]


def defs_in(nb) -> dict[str, ast.FunctionDef]:
    out = {}
    for text in code_cells(nb):
        for node in ast.parse(text).body:
            if isinstance(node, ast.FunctionDef):
                out[node.name] = node
    return out


def reference_def(name: str) -> ast.FunctionDef:
    path = nbk.find_module(name, KIT_ROOT / "solutions")
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == name)


def without_docstring(body):
    return body[1:] if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) else body


# ---------------------------------------------------------------------------------- one source


@pytest.mark.parametrize("variant", nbk.VARIANTS)
@pytest.mark.parametrize("stem", NOTEBOOKS)
def test_committed_notebook_is_exactly_the_build(stem, variant):
    nb = committed(stem, variant)
    fresh = nbk.build_notebook(stem, variant, nbk.settings_of(nb))
    assert json.loads(nbformat.writes(fresh)) == json.loads(nbk.output_path(stem, variant).read_text())


def test_check_option_reports_a_stale_notebook(tmp_path, monkeypatch):
    from kit.notebooks import build

    # One build for the three calls below (a build of every notebook takes about 2 s): the sources
    # they build from do not change in between, only the written notebook the test edits.
    built = build.build_all(root=tmp_path)
    roots = []

    def built_once(settings=None, *, root=None):
        roots.append(root)
        return built

    monkeypatch.setattr(build, "build_all", built_once)
    nbk.write_all(root=tmp_path)
    assert nbk.outdated(root=tmp_path) == []
    stale = nbk.output_path("q3_metric_reconstruction", "student", tmp_path)
    nb = nbformat.read(stale, as_version=4)
    nb.cells[-1].source += "\n# edited by hand"
    nbformat.write(nb, stale)
    assert nbk.outdated(root=tmp_path) == [stale]
    assert roots == [tmp_path] * 3


@pytest.mark.parametrize("name", ALL_FUNCTIONS)
def test_answer_key_holds_the_reference_verbatim(name):
    stem = next(q.notebook for q in QUESTIONS if name in q.functions)
    got = defs_in(committed(stem, "key"))[name]
    assert ast.dump(got) == ast.dump(reference_def(name))


@pytest.mark.parametrize("name", ALL_FUNCTIONS)
def test_student_stub_keeps_the_contract_and_nothing_else(name):
    stem = next(q.notebook for q in QUESTIONS if name in q.functions)
    stub = defs_in(committed(stem, "student"))[name]
    ref = reference_def(name)
    # The reference's keyword-only switches and its method section are the answer key's only
    # (tests/starter_tests/test_stub_contracts.py checks the contract itself).
    assert [a.arg for a in stub.args.args] == [a.arg for a in ref.args.args] and not stub.args.kwonlyargs
    assert ast.get_docstring(ref, clean=False).startswith(ast.get_docstring(stub, clean=False).rstrip())
    body = without_docstring(stub.body)
    assert len(body) == 1 and isinstance(body[0], ast.Raise)
    assert ast.unparse(body[0].exc) == "NotImplementedError()"


# ------------------------------------------------------------------------- no answers leak


def _statements(trees) -> set[str]:
    return {ast.dump(n) for t in trees for n in ast.walk(t) if isinstance(n, ast.stmt)}


def _reference_statements(min_nodes: int = 8) -> dict[str, str]:
    """ast dump -> where, for every statement of every solutions function big enough to be telling."""
    out = {}
    for path in sorted((KIT_ROOT / "solutions").glob("*.py")):
        for fn in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(fn, ast.FunctionDef):
                for stmt in without_docstring(fn.body):
                    for node in ast.walk(stmt):
                        if isinstance(node, ast.stmt) and sum(1 for _ in ast.walk(node)) >= min_nodes:
                            out[ast.dump(node)] = f"{path.stem}.{fn.name}, line {node.lineno}"
    return out


@pytest.mark.parametrize("stem", NOTEBOOKS)
def test_student_notebook_has_no_reference_code(stem):
    nb = committed(stem, "student")
    trees = [ast.parse(text) for text in code_cells(nb)]
    found = _statements(trees)
    leaked = [where for dump, where in _reference_statements().items() if dump in found]
    assert leaked == []
    bodies = set(reference_bodies().values())
    for t in trees:
        for fn in ast.walk(t):
            if isinstance(fn, ast.FunctionDef):
                assert "\n".join(ast.dump(s) for s in without_docstring(fn.body)) not in bodies, fn.name
    text = "\n".join(code_cells(nb))
    assert not re.search(r"^\s*(from|import)\s+solutions\b", text, flags=re.MULTILINE)
    assert nbk.BEGIN not in text and nbk.END not in text


def test_solution_regions_of_the_sources_stay_out_of_student_notebooks():
    checked = 0
    for stem in NOTEBOOKS:
        blocks = nbk.parse_source((nbk.SRC_DIR / f"{stem}.md").read_text(), stem)
        student = "\n".join(code_cells(committed(stem, "student")))
        key = "\n".join(code_cells(committed(stem, "key")))
        for b in blocks:
            if b.kind != "python" or nbk.BEGIN not in b.text:
                continue
            region = b.text.split(nbk.BEGIN)[1].split(nbk.END)[0]
            for line in filter(str.strip, region.splitlines()):
                assert line not in student
                assert line in key
                checked += 1
    assert checked > 0  # q1 has such a region: the test must have looked at it


def test_leak_scan_finds_a_planted_reference_body(tmp_path):
    planted = reference_def("triangulate")
    planted.name = "my_triangulate"  # renamed and re-typed: the body is what gives it away
    (tmp_path / "helper.py").write_text("import numpy as np\n\n\n" + ast.unparse(planted))
    (tmp_path / "other.py").write_text("import numpy as np\nfrom solutions.pose import findM2\n")
    (tmp_path / "sly.py").write_text("import importlib\npose = importlib.import_module('solutions.pose')\n")
    problems = leaks(tmp_path)
    assert any("sly.py" in p and "solutions" in p for p in problems)
    assert any("helper.py" in p and "triangulation.triangulate" in p for p in problems)
    assert any("other.py" in p and "solutions" in p for p in problems)


# --------------------------------------------------------------------------- notebook shape


@pytest.mark.parametrize("variant", nbk.VARIANTS)
@pytest.mark.parametrize("stem", NOTEBOOKS)
def test_every_question_heading_with_its_points(stem, variant):
    nb = committed(stem, variant)
    headings = {}
    for c in nb.cells:
        if c.cell_type == "markdown":
            m = re.match(QUESTION_HEADING, c.source.splitlines()[0])
            if m:
                headings[m.group(1)] = c.source.splitlines()[0]
    expected = [q for q in QUESTIONS if q.notebook == stem]
    assert sorted(headings) == sorted(q.id for q in expected)
    for q in expected:
        assert f"{q.id} {q.title} [{q.points} points" in headings[q.id]
        assert ("extra credit" in headings[q.id]) == q.extra_credit


@pytest.mark.parametrize("stem", NOTEBOOKS)
def test_colab_link_then_setup_cell_first(stem):
    nb = committed(stem, "student")
    settings = nbk.settings_of(nb)
    assert any(settings.colab_url(stem) in c.source for c in nb.cells if c.cell_type == "markdown")
    first = code_cells(nb)[0]
    assert f'KIT_REPO = "{settings.repo_url}"' in first and "google.colab" in first
    # Colab: the student's work lives in Google Drive, where later notebooks and the hand-in find it.
    assert "drive.mount(" in first and '"MyDrive"' in first and "HW4_NOTEBOOKS" in first
    assert "enable_custom_widget_manager()" in first


def test_settings_reach_the_links_and_the_setup_cell():
    s = nbk.Settings("https://github.com/cmu-course/hw4-release", "spring")
    nb = nbk.build_notebook("q2_eightpoint", "student", s)
    text = "\n".join(c.source for c in nb.cells)
    assert "https://colab.research.google.com/github/cmu-course/hw4-release/blob/spring/notebooks/q2_eightpoint.ipynb" in text
    assert 'KIT_REPO = "https://github.com/cmu-course/hw4-release"' in text and 'KIT_REF = "spring"' in text
    assert "Placeholder" not in text
    assert "Placeholder" in "\n".join(c.source for c in nbk.build_notebook("q2_eightpoint", "student",
                                                                            nbk.Settings()).cells)


@pytest.mark.parametrize("url", ["https://gitlab.com/a/b", "github.com/a/b", "https://github.com/a"])
def test_settings_reject_a_repository_colab_cannot_open(url):
    with pytest.raises(ValueError, match="repo_url"):
        nbk.Settings(url)


def test_a_local_repository_is_cloned_but_gets_no_colab_link():
    s = nbk.Settings("file:///srv/git/hw4")
    assert s.colab_url("q2_eightpoint") is None
    text = "\n".join(c.source for c in nbk.build_notebook("q2_eightpoint", "student", s).cells)
    assert 'KIT_REPO = "file:///srv/git/hw4"' in text and "colab.research.google.com" not in text


def test_the_placeholder_is_refused_for_anything_handed_out(tmp_path, capsys):
    from kit.__main__ import main as kit_main

    with pytest.raises(ValueError, match="--repo-url https://github.com/ORG/REPO"):
        nbk.Settings().require_repository("python -m kit release")
    assert kit_main(["release", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert "placeholder" in err and "--repo-url" in err and "settings.json" in err
    assert not (tmp_path / "r").exists()
    assert kit_main(["notebooks", "--out", str(tmp_path / "n")]) == 2
    assert "--repo-url" in capsys.readouterr().err and not (tmp_path / "n").exists()
    # The kit's own committed build keeps the placeholder (kit release rebuilds for the real one).
    assert nbk.load_settings().is_placeholder or not nbk.settings_of(committed("q2_eightpoint", "student")).is_placeholder


@pytest.mark.parametrize("stem", NOTEBOOKS)
def test_every_function_has_a_stub_cell_and_a_check_cell(stem):
    nb = committed(stem, "student")
    cells = code_cells(nb)
    for name in functions_of_notebook(stem):
        assert sum(f"def {name}(" in c for c in cells) == 1
        if name != "plot_3d_keypoint_video":  # a figure: its check is the figure cell
            module = nbk.extract_function(name).module
            assert sum(f"from starter.checks.{module} import check_{name}" in c for c in cells) == 1


def test_q1_has_two_hand_graded_answer_cells():
    student, key = committed("q1_proofs", "student"), committed("q1_proofs", "key")
    answers = [c for c in student.cells if c.cell_type == "markdown" and c.source == nbk.ANSWER_PLACEHOLDER]
    assert len(answers) == 2
    key_text = "\n".join(c.source for c in key.cells)
    assert "f_{33} = 0" in key_text and "R}_{rel} = \\mathbf{R}_{i+1}\\mathbf{R}_i^T" in key_text


def test_nbgrader_metadata_and_points():
    points: dict[str, int] = {}
    for stem in NOTEBOOKS:
        nb = committed(stem, "nbgrader")
        ids = [c.metadata["nbgrader"]["grade_id"] for c in nb.cells if "nbgrader" in c.metadata]
        assert len(ids) == len(set(ids))
        question = None
        for c in nb.cells:
            m = re.match(QUESTION_HEADING, c.source.splitlines()[0]) if c.cell_type == "markdown" else None
            question = m.group(1) if m else question
            meta = c.metadata.get("nbgrader")
            if meta is None:
                continue
            assert meta["schema_version"] == 3
            if meta["grade"]:
                points[question] = points.get(question, 0) + meta["points"]
                assert meta["solution"] == (c.cell_type == "markdown")
            if meta["solution"] and c.cell_type == "code" and meta["grade_id"] in ALL_FUNCTIONS:
                assert f"def {meta['grade_id']}(" in c.source and nbk.BEGIN in c.source
    assert points == {q.id: q.points for q in QUESTIONS}


def _nbgrader_namespace(stem: str) -> dict:
    ns: dict = {}
    for c in committed(stem, "nbgrader").cells:
        if c.cell_type == "code" and c.metadata.get("nbgrader", {}).get("solution"):
            exec(compile(c.source, f"{stem} (nbgrader)", "exec"), ns)  # noqa: S102 - our own source
    return ns


def test_nbgrader_solutions_compute_what_the_reference_does(two_view):
    """Helpers and imports nested in the region must not change the answers."""
    g = {**_nbgrader_namespace("q2_eightpoint"), **_nbgrader_namespace("q3_metric_reconstruction")}
    rng = np.random.default_rng(3)
    p1 = two_view["pts1"] + rng.normal(0, 0.3, two_view["pts1"].shape)
    p2 = two_view["pts2"] + rng.normal(0, 0.3, two_view["pts2"].shape)
    F_ref = solutions.eightpoint(p1, p2, 640.0, refine=False)
    # The handout's signature: the nbgrader solution refines as the reference does by default.
    np.testing.assert_allclose(g["eightpoint"](p1, p2, 640.0), solutions.eightpoint(p1, p2, 640.0))
    K1, K2 = two_view["K1"], two_view["K2"]
    np.testing.assert_allclose(g["essentialMatrix"](F_ref, K1, K2), solutions.essentialMatrix(F_ref, K1, K2))
    w, err = g["triangulate"](two_view["C1"], p1, two_view["C2"], p2)
    w_ref, err_ref = solutions.triangulate(two_view["C1"], p1, two_view["C2"], p2)
    np.testing.assert_allclose(w, w_ref)
    assert err == pytest.approx(err_ref)
    for got, want in zip(g["findM2"](F_ref, p1, p2, K1, K2), solutions.findM2(F_ref, p1, p2, K1, K2)):
        np.testing.assert_allclose(got, want)
    q5 = _nbgrader_namespace("q5_bundle_adjustment")
    from starter import invRodrigues

    M1 = np.hstack([np.eye(3), np.zeros((3, 1))])
    R, t = two_view["M2"][:, :3], two_view["M2"][:, 3]
    x = np.concatenate([two_view["X"].ravel() * 1.01, invRodrigues(R), t])
    np.testing.assert_allclose(q5["rodriguesResidual"](K1, M1, p1, K2, p2, x),
                               solutions.rodriguesResidual(K1, M1, p1, K2, p2, x))
    got = q5["bundleAdjustment"](K1, M1, p1, K2, two_view["M2"], p2, w_ref)
    want = solutions.bundleAdjustment(K1, M1, p1, K2, two_view["M2"], p2, w_ref)
    assert got[3] == pytest.approx(want[3], rel=1e-6)

    q4 = _nbgrader_namespace("q4_temple_3d")
    im1 = rng.integers(0, 256, size=(60, 80, 3), dtype=np.uint8)
    im2 = np.roll(im1, 2, axis=0)
    F = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])  # lines x2 = x1
    for x, y in [(20, 30), (40, 12), (70, 45)]:
        assert q4["epipolarCorrespondence"](im1, im2, F, x, y) == solutions.epipolarCorrespondence(im1, im2, F, x, y)

    q6 = _nbgrader_namespace("q6_multiview_car")
    C3 = two_view["K1"] @ np.hstack([np.eye(3), np.array([[0.5], [0.0], [0.0]])])
    p3 = project(C3, two_view["X"]) + rng.normal(0, 0.3, p1.shape)
    views = [(C, np.column_stack([pts, rng.choice([300.0, 600.0], len(pts))]))
             for C, pts in ((two_view["C1"], p1), (two_view["C2"], p2), (C3, p3))]
    args = [a for view in views for a in view] + [400]
    got, want = q6["MultiviewReconstruction"](*args), solutions.MultiviewReconstruction(*args)
    np.testing.assert_allclose(got[0], want[0])
    assert got[1] == pytest.approx(want[1])


@pytest.mark.parametrize("stem", NOTEBOOKS)
def test_written_answers_only_where_they_belong(stem):
    blocks = [b for b in nbk.parse_source((nbk.SRC_DIR / f"{stem}.md").read_text(), stem) if b.kind == "answer"]
    markdown = {v: [c for c in committed(stem, v).cells if c.cell_type == "markdown"] for v in nbk.VARIANTS}
    for b in blocks:
        assert any(c.source == b.text for c in markdown["key"])
        assert not any(b.text in c.source for c in markdown["student"])
        in_nbgrader = [c for c in markdown["nbgrader"] if c.source == b.text]
        if "ungraded" in b.args:
            assert in_nbgrader == []
        else:
            assert len(in_nbgrader) == 1
            meta = in_nbgrader[0].metadata["nbgrader"]
            assert meta["solution"] and meta["grade"] and meta["points"] > 0
    placeholders = sum(c.source == nbk.ANSWER_PLACEHOLDER for c in markdown["student"])
    assert placeholders == len(blocks)


# ------------------------------------------------------------------------------ the builder


def test_parse_source_cells_and_directives():
    text = "# Title\n\nintro\n+++\nmore\n```python figure\nx = 1\n```\n## Q2\nbody\n```text\n+++\n```\n" \
           "```{solution} eightpoint\n```\n"
    blocks = nbk.parse_source(text)
    assert [(b.kind, b.args) for b in blocks] == [
        ("markdown", ()), ("markdown", ()), ("python", ("figure",)), ("markdown", ()), ("solution", ("eightpoint",))]
    assert blocks[3].text.startswith("## Q2\nbody\n```text\n+++")  # a fence in markdown is left alone


def test_plus_lines_mark_a_page_start_and_plumbing_for_the_pdf():
    from handin.html import PAGE_START_TAG, PLUMBING_TAG

    blocks = nbk.parse_source("intro\n+++ plumbing\nhow to use Colab\n+++ page\n### Errors (Q3.2)\ntext\n+++\nplain\n")
    assert [(b.args, b.text.splitlines()[0]) for b in blocks] == [
        ((), "intro"), (("plumbing",), "how to use Colab"), (("page",), "### Errors (Q3.2)"), ((), "plain")]
    q3 = nbk.build_notebook("q3_metric_reconstruction", "student")
    (page,) = [c for c in q3.cells if PAGE_START_TAG in c.metadata.get("tags", [])]
    assert page.source.startswith("### Reprojection errors (Q3.2")
    q1 = nbk.build_notebook("q1_proofs", "student")
    plumbing = [c for c in q1.cells if PLUMBING_TAG in c.metadata.get("tags", [])]
    # The Colab how-to, the Colab link and the setup cell: the kit's, not the student's work.
    assert [c.cell_type for c in plumbing] == ["markdown", "markdown", "code"]
    assert plumbing[0].source.startswith("**Working on Colab.**")


@pytest.mark.parametrize("text, message", [
    ("```python\nx = 1\n", "never closed"),
    ("## Q2 The eight-point algorithm [10 points]\n", "bare"),
    ("+++ pagebreak\ntext\n", "'\\+\\+\\+ WORD'"),
    ("+++ page\n```python\nx = 1\n```\n", "followed by a markdown cell"),
])
def test_parse_source_rejects(text, message):
    with pytest.raises(nbk.SourceError, match=message):
        nbk.parse_source(text, "bad.md")


def test_solution_regions_per_variant():
    src = "def f(x):\n    y = 2\n    ### BEGIN SOLUTION\n    return x * y\n    ### END SOLUTION\n"
    assert nbk.clear_regions(src, "key", "t")[0] == "def f(x):\n    y = 2\n    return x * y"
    assert nbk.clear_regions(src, "student", "t")[0] == \
        "def f(x):\n    y = 2\n    # YOUR CODE HERE\n    raise NotImplementedError()"
    assert nbk.clear_regions(src, "nbgrader", "t") == (src.rstrip("\n"), True)
    with pytest.raises(nbk.SourceError, match="never closed"):
        nbk.clear_regions("### BEGIN SOLUTION\nx = 1\n", "key", "t")


def _source_copy(tmp_path, stem, edit):
    src = tmp_path / "src"
    src.mkdir()
    for p in nbk.SRC_DIR.iterdir():
        (src / p.name).write_text(p.read_text())
    path = src / f"{stem}.md"
    path.write_text(edit(path.read_text()))
    return src


@pytest.mark.parametrize("stem, edit, message", [
    ("q3_metric_reconstruction",
     lambda s: s.replace("```{solution} findM2\n```", "").replace("```{check} findM2\n```", ""), "solution cells"),
    ("q3_metric_reconstruction", lambda s: s.replace("## Q3.3\n", ""), "question above"),
    ("q3_metric_reconstruction",
     lambda s: s.replace("```{solution} essentialMatrix\n```", "").replace("```{check} essentialMatrix\n```", ""),
     "calls"),
    ("q4_temple_3d", lambda s: s.replace("findM2, triangulate = from_notebook", "findM2 = from_notebook"), "calls"),
    ("q2_eightpoint", lambda s: s.replace("```{setup}\n```", ""), "setup"),
])
def test_builder_rejects_a_broken_source(tmp_path, stem, edit, message):
    src = _source_copy(tmp_path, stem, edit)
    with pytest.raises(nbk.SourceError, match=message):
        nbk.build_notebook(stem, "key", src_dir=src)


def test_points_that_do_not_add_up_are_rejected(tmp_path):
    src = _source_copy(tmp_path, "q6_multiview_car", lambda s: s.replace("{answer} Q6 ungraded", "{answer} Q6 points=16"))
    with pytest.raises(nbk.SourceError, match="points"):
        nbk.build_notebook("q6_multiview_car", "nbgrader", src_dir=src)


FAKE_SOLUTION = """\
from __future__ import annotations

import numpy as np
import scipy.optimize
import scipy.sparse
from core.validate import as_matrix, as_points

from .triangulation import triangulate

_SCALE = 2.0


def _square(x):
    return scipy.optimize.rosen(x) + _SCALE


def _unused(x):
    return scipy.sparse.eye(3)


def _twice(x):
    return 2 * _square(x)


def findM2(F, pts1, pts2, K1, K2):
    \"\"\"Docstring: the contract.\"\"\"
    F = as_matrix(F, "F", (3, 3))
    return _twice(np.ones(3)), triangulate
"""


def test_extract_function_takes_helpers_and_trims_imports(tmp_path):
    (tmp_path / "pose.py").write_text(FAKE_SOLUTION)
    ext = nbk.extract_function("findM2", tmp_path)
    assert ext.module == "pose" and ext.needs == ("triangulate",)
    assert [name for name, _ in ext.helpers] == ["_SCALE", "_square", "_twice"]
    assert ext.imports == ("import numpy as np", "import scipy.optimize", "from core.validate import as_matrix")
    assert ext.header.endswith('"""Docstring: the contract."""')
    assert ext.body.splitlines()[0] == '    F = as_matrix(F, "F", (3, 3))'
    (tmp_path / "pose.py").write_text(FAKE_SOLUTION.replace("from .triangulation import triangulate",
                                                            "from .triangulation import _private"))
    with pytest.raises(nbk.SourceError, match="_private"):
        nbk.extract_function("findM2", tmp_path)
    (tmp_path / "pose.py").write_text(FAKE_SOLUTION.replace('    \"\"\"Docstring: the contract.\"\"\"\n', ""))
    with pytest.raises(nbk.SourceError, match="docstring"):
        nbk.extract_function("findM2", tmp_path)


def test_real_solutions_extract_with_their_sibling_calls():
    assert nbk.extract_function("compute3D_pts").needs == ("epipolarCorrespondence", "triangulate")
    assert nbk.extract_function("findM2").needs == ("essentialMatrix", "triangulate")
    assert nbk.extract_function("eightpoint").needs == ()


# ------------------------------------------------------------------------ notebook helpers


def _write_nb(path: Path, *cells: str) -> Path:
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(c) for c in cells])
    nbformat.write(nb, path)
    return path


def test_from_notebook_runs_only_definitions(tmp_path):
    _write_nb(tmp_path / "a.ipynb", "import numpy as np\nraise RuntimeError('figure cell')",
              "%matplotlib inline\ndef double(x):\n    return 2 * np.asarray(x)", "print(undefined_name)")
    _write_nb(tmp_path / "b.ipynb", "from starter.notebook_import import from_notebook",
              "double = from_notebook('a.ipynb', 'double')\ndef quadruple(x):\n    return double(double(x))")
    quadruple = from_notebook("b.ipynb", "quadruple", folder=tmp_path)
    assert quadruple(3) == 12  # the chain b -> a resolves next to b, not in the current folder
    double, quad = from_notebook(tmp_path / "b.ipynb", "double", "quadruple")
    assert double(1) == 2 and quad(1) == 4
    kinds = [type(node).__name__ for _, node, _ in notebook_definitions("a.ipynb", tmp_path)]
    assert kinds == ["Import", "FunctionDef"]


def test_from_notebook_errors_say_what_to_do(tmp_path):
    _write_nb(tmp_path / "a.ipynb", "def f():\n    return 1")
    with pytest.raises(ImportError, match="defines no g.*defines: f"):
        from_notebook("a.ipynb", "g", folder=tmp_path)
    with pytest.raises(FileNotFoundError, match="Save a copy in Drive"):
        from_notebook("missing.ipynb", "f", folder=tmp_path)
    with pytest.raises(ValueError, match="names"):
        from_notebook("a.ipynb", folder=tmp_path)
    with pytest.raises(ValueError, match="ipynb"):
        from_notebook("a.py", "f", folder=tmp_path)
    imp = "from starter.notebook_import import from_notebook\n"
    _write_nb(tmp_path / "x.ipynb", imp + "g = from_notebook('y.ipynb', 'g')")
    _write_nb(tmp_path / "y.ipynb", imp + "g = from_notebook('x.ipynb', 'g')")
    with pytest.raises(ImportError, match="cycle"):
        from_notebook("x.ipynb", "g", folder=tmp_path)


def test_try_run_reports_stubs_and_contains_real_errors(capsys):
    def stub(x):
        raise NotImplementedError()

    def check(fn):
        return fn(1)

    def inner(x):
        return [][x]

    def outer():
        return inner(3)

    assert try_run(stub, 1) is None
    assert try_run(check, stub) is None
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("stub: not implemented yet") and "(check skipped)" in out[1]
    assert try_run(lambda a, b=0: a + b, 1, b=2) == 3
    # A real error is one short line naming the function called and where it was raised; the
    # caller gets None, so the cells after it still run.
    assert try_run(outer) is None
    (line,) = capsys.readouterr().out.splitlines()
    assert line.startswith("outer failed: IndexError: list index out of range (raised in inner, line ")
    assert "call it directly to see the traceback" in line
    with pytest.raises(KeyboardInterrupt):
        try_run(lambda: (_ for _ in ()).throw(KeyboardInterrupt))


# ------------------------------------------------------------------------------- the release


@pytest.fixture(scope="module")
def release(tmp_path_factory):
    data = tmp_path_factory.mktemp("data")
    (data / "temple").mkdir()
    (data / "temple" / "some_corresp.npz").write_bytes(b"placeholder")
    (data / "official").mkdir()
    (data / "official" / "secret.txt").write_text("course data")
    out = tmp_path_factory.mktemp("release") / "hw4"
    files = write_release(out, data=data, settings=RELEASE_SETTINGS)
    return out, files


RELEASE_SETTINGS = nbk.Settings("https://github.com/cmu-course/hw4-release", "spring")


def test_release_notebooks_point_to_its_repository(release):
    out, _ = release
    for p in (out / "notebooks").iterdir():
        nb = nbformat.read(p, as_version=4)
        first = code_cells(nb)[0]
        assert 'KIT_REPO = "https://github.com/cmu-course/hw4-release"' in first and 'KIT_REF = "spring"' in first
        assert "YOUR-ORG" not in nbformat.writes(nb)
    assert "colab.research.google.com/github/cmu-course/hw4-release/blob/spring" in (out / "README.md").read_text()


def test_release_holds_the_student_kit_only(release):
    out, files = release
    assert {p.name for p in out.iterdir()} == set(RELEASE_TOP) & (
        set(release_packages()) | {"data", "notebooks", "requirements.txt", "pyproject.toml", "README.md", ".gitignore"})
    assert set(STUDENT_PACKAGES) <= set(release_packages()) and {"core", "handin"} <= set(STUDENT_PACKAGES)
    for gone in ("solutions", "autograder", "tests", "benchmarks", "kit", "notebooks/key", "notebooks/nbgrader",
                 "notebooks/src", "data/official", *NEVER_TO_STUDENTS):
        assert not (out / gone).exists()
    # Nothing in the release imports a package that does not ship (kit, autograder, solutions...).
    shipped = {p.name for p in out.iterdir() if (p / "__init__.py").is_file()}
    kit_packages = {p.name for p in KIT_ROOT.iterdir() if (p / "__init__.py").is_file()}
    for path in files:
        if path.suffix == ".py":
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                         [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else [])
                for name in names:
                    top = name.split(".")[0]
                    assert top in shipped or top not in kit_packages, f"{path.relative_to(out)} imports {name}"
    assert sorted(p.name for p in (out / "notebooks").iterdir()) == sorted(
        [f"{s}.ipynb" for s in NOTEBOOKS] + ["hand_in.ipynb"])
    for p in (out / "notebooks").iterdir():
        if p.name != "hand_in.ipynb":
            assert nbformat.read(p, as_version=4).metadata["hw4_kit"]["variant"] == "student"
    assert not (out / "data" / "official").exists() and (out / "data" / "temple" / "some_corresp.npz").exists()
    assert (out / "handin" / "pdf_assets" / "hw4.css").exists() and (out / "core" / "notebook.py").exists()
    assert not any("__pycache__" in p.parts for p in files)
    assert (out / "starter" / "notebook_import.py").exists()


def test_release_gives_no_answer_away(release):
    out, files = release
    assert leaks(out) == []
    bodies = set(reference_bodies().values())
    for p in files:
        if p.suffix == ".py":
            sources = [p.read_text()]
        elif p.suffix == ".ipynb":
            sources = code_cells(nbformat.read(p, as_version=4))
        else:
            continue
        for text in sources:
            assert not re.search(r"^\s*(from|import)\s+solutions\b", text, flags=re.MULTILINE), p
            for fn in ast.walk(ast.parse(text)):
                if isinstance(fn, ast.FunctionDef):
                    assert "\n".join(ast.dump(s) for s in without_docstring(fn.body)) not in bodies, (p, fn.name)


def test_release_is_installable_as_declared(release):
    out, _ = release
    meta = tomllib.loads((out / "pyproject.toml").read_text())
    for package in meta["tool"]["setuptools"]["packages"]:
        assert (out / package.replace(".", "/") / "__init__.py").exists()
    assert meta["tool"]["setuptools"]["dynamic"]["dependencies"]["file"] == ["requirements.txt"]
    assert (out / "requirements.txt").read_text() == (KIT_ROOT / "requirements.txt").read_text()
    readme = (out / "README.md").read_text()
    assert all(f"notebooks/{s}.ipynb" in readme for s in NOTEBOOKS)


def test_release_refuses_unsafe_targets(release, tmp_path):
    out, _ = release
    with pytest.raises(ValueError, match="outside the kit"):
        write_release(KIT_ROOT / "build" / "release", settings=RELEASE_SETTINGS)
    with pytest.raises(ValueError, match="empty"):
        write_release(out, data=out / "data", settings=RELEASE_SETTINGS)
    (tmp_path / "keep.txt").write_text("mine")
    write_release(tmp_path, data=out / "data", force=True, settings=RELEASE_SETTINGS)
    assert (tmp_path / "keep.txt").read_text() == "mine" and (tmp_path / "starter").is_dir()


# ------------------------------------------------------------------- running the notebooks


# requirements-dev.txt names -> the modules they install.  The notebooks must run without them
# (students install requirements.txt only), so the kernels below see each as missing.
DEV_ONLY_MODULES = {"pytest": "pytest", "opencv-python-headless": "cv2", "jupyterlab": "jupyterlab",
                    "playwright": "playwright", "nbgrader": "nbgrader", "pytest-xdist": "xdist",
                    "kubernetes": "kubernetes"}


def _requirement_names(path: Path) -> set[str]:
    names = set()
    for line in path.read_text().splitlines():
        line = line.split("#")[0].strip()
        if line and not line.startswith("-"):
            names.add(re.split(r"[<>=!~\[ ;]", line)[0].lower())
    return names


def test_every_dev_only_requirement_is_hidden_from_the_notebook_kernels():
    dev_only = _requirement_names(KIT_ROOT / "requirements-dev.txt") - _requirement_names(KIT_ROOT / "requirements.txt")
    assert dev_only <= set(DEV_ONLY_MODULES)


@pytest.fixture(scope="session")
def without_dev_packages(tmp_path_factory) -> Path:
    """A folder of stand-in modules that raise ImportError, put first on the kernels' path."""
    folder = tmp_path_factory.mktemp("no-dev-packages")
    for module in DEV_ONLY_MODULES.values():
        (folder / f"{module}.py").write_text(
            f"raise ImportError('{module} is a development dependency, not in requirements.txt')\n")
    return folder


def execute(path: Path, data: Path, monkeypatch, *, allow_errors: bool = False,
            hide: Path | None = None) -> nbformat.NotebookNode:
    from nbclient import NotebookClient

    monkeypatch.setenv("HW4_DATA", str(data))
    if hide is not None:
        monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(hide), os.environ.get("PYTHONPATH", "")]))
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    nb = nbformat.read(path, as_version=4)
    # A per-cell limit: a hang fails the test instead of stalling the suite.
    NotebookClient(nb, timeout=60, kernel_name="python3", allow_errors=allow_errors,
                   resources={"metadata": {"path": str(path.parent)}}).execute()
    return nb


def outputs_text(cell) -> str:
    return "".join(o.get("text", "") for o in cell.get("outputs", []) if o.output_type == "stream")


@pytest.mark.slow
@pytest.mark.parametrize("stem", NOTEBOOKS)
def test_answer_key_runs_and_keeps_every_figure_as_png(stem, homework_data, monkeypatch, without_dev_packages):
    nb = execute(nbk.output_path(stem, "key"), homework_data, monkeypatch, hide=without_dev_packages)
    figures = [c for c in nb.cells if "figure" in c.metadata.get("tags", [])]
    assert figures or stem == "q1_proofs"
    for cell in figures:
        kinds = [set(o.get("data", {})) for o in cell.outputs]
        assert any("image/png" in k for k in kinds), cell.source[:80]
    text = "\n".join(outputs_text(c) for c in nb.cells if c.cell_type == "code")
    assert "not implemented yet" not in text
    if stem == "q1_proofs":  # the key's formulas pass the numeric check of Q1.2
        assert "(right)" in text and "not right" not in text


@pytest.mark.slow
@pytest.mark.parametrize("stem", NOTEBOOKS)
def test_student_notebook_runs_with_stubs(stem, homework_data, monkeypatch, without_dev_packages):
    nb = execute(nbk.output_path(stem, "student"), homework_data, monkeypatch, hide=without_dev_packages)
    text = "\n".join(outputs_text(c) for c in nb.cells if c.cell_type == "code")
    for name in functions_of_notebook(stem):
        if name != "plot_3d_keypoint_video":
            assert f"check {name}: not implemented yet" in text
    assert "not implemented yet" in text


@pytest.mark.slow
def test_a_crash_stops_its_own_step_only(tmp_path, homework_data, monkeypatch):
    """An eightpoint that raises (not a stub) makes each step that needs it print one line naming
    it; every cell of Q3's notebook still runs (no NameError cascade) and the checks report."""
    _write_nb(tmp_path / "q2_eightpoint.ipynb", "def eightpoint(pts1, pts2, M):\n    return [][len(pts1)]")
    shutil.copy(nbk.output_path("q3_metric_reconstruction", "key"), tmp_path)
    nb = execute(tmp_path / "q3_metric_reconstruction.ipynb", homework_data, monkeypatch)  # raises on any error
    text = "\n".join(outputs_text(c) for c in nb.cells if c.cell_type == "code")
    assert "eightpoint failed: IndexError: list index out of range" in text
    last = [c for c in nb.cells if c.cell_type == "code"][-1]
    assert "reprojection_errors(" in last.source and "eightpoint failed" in outputs_text(last)
    assert "check findM2: 3/3 passed" in text


@pytest.mark.slow
def test_nbgrader_source_runs(homework_data, monkeypatch):
    """A source whose regions nest helpers and imports runs in a kernel; every cell but the graded
    checks (whose verdict is the checks' business) runs cleanly."""
    nb = execute(nbk.output_path("q5_bundle_adjustment", "nbgrader"), homework_data, monkeypatch,
                 allow_errors=True)
    for cell in nb.cells:
        if cell.cell_type == "code" and not cell.metadata.get("nbgrader", {}).get("grade"):
            assert not [o for o in cell.outputs if o.output_type == "error"], cell.source[:80]


@pytest.mark.slow
def test_nbgrader_release_of_the_source_is_the_student_notebook(tmp_path):
    """nbgrader's own generate_assignment, where installed, turns our source into our student notebooks."""
    pytest.importorskip("nbgrader")
    import shutil

    (tmp_path / "source").mkdir()
    shutil.copytree(nbk.output_path(NOTEBOOKS[0], "nbgrader").parent, tmp_path / "source" / "hw4")
    (tmp_path / "nbgrader_config.py").write_text(
        f"c = get_config()\nc.CourseDirectory.course_id = 'hw4'\nc.CourseDirectory.root = {str(tmp_path)!r}\n")
    from autograder.channels.nbgrader.course import run_nbgrader

    run_nbgrader(tmp_path, "generate_assignment", "hw4", "--force", timeout=300)   # raises with the log on failure
    for stem in NOTEBOOKS:
        released = nbformat.read(tmp_path / "release" / "hw4" / f"{stem}.ipynb", as_version=4)
        ours = committed(stem, "student")
        assert len(released.cells) == len(ours.cells)
        for a, b in zip(released.cells, ours.cells):
            graded_test = a.metadata.get("nbgrader", {}).get("grade") and not a.metadata["nbgrader"]["solution"]
            if not graded_test:  # our student check cells only drop the assert line
                assert (a.cell_type, a.source) == (b.cell_type, b.source)
