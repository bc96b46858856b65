"""Nothing that ships to students looks like a reference solution, by the review's own fingerprints.

``kit.release.leaks`` catches a reference body copied as it is (same ast).  These tests catch
one rewritten: renamed variables, reordered statements, a function cut into helpers.  They read
the code the way ``python -m autograder similar`` reads submissions (autograder.review:
normalised-AST fingerprints, the same score and the same FLAG), with two readers in mind:

- per function: every function of what ships (each module of the packages ``core.shipping``
  sends to students, and every code cell of the student notebooks) scored against every
  function of solutions/ (the answers to the graded questions, their helpers, and the other
  correct styles kept there: solutions.matching_styles, solutions.twisted_pair) as two
  submissions would be; a pair at FLAG or above is a leak;
- as a whole: the shipped packages read as one submission (``given_hashes`` of them, the
  handout's code as the review subtracts it) scored against each graded function's answer (its
  reference definition less what the student notebooks' stubs give on purpose).  A reference cut
  into several shipped helpers, none alike enough alone, is found here; the review would also
  discount it as code "the handout explains", so copies of it would go unseen.

Each test names what it found; a helper the handout gives may ship, a working answer may not.
Text is all these tests read: code that computes an answer in other words is found by running it
(tests/repository/test_behaviour_leaks.py calls every shipped callable on the graded functions' inputs).
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import nbformat
import numpy as np
import pytest

from autograder.review.fingerprint import Fingerprints, fingerprint_code
from autograder.review.similarity import (FLAG, CONTAINMENT_DISCOUNT, MIN_SHARED, code_hashes, compare_function,
                                         given_hashes)
from core.manifest import QUESTIONS
from core.paths import KIT_ROOT, NOTEBOOKS_DIR
from core.shipping import STUDENT_NOTEBOOKS
from kit.release import release_packages

SOLUTIONS = KIT_ROOT / "solutions"
GRADED = tuple(f for q in QUESTIONS for f in q.functions)


def _functions(tree: ast.AST, where: str) -> list[tuple[str, Fingerprints]]:
    """(where:qualified name, fingerprints) of every function in ``tree``, nested ones and methods too."""
    out = []

    def visit(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                name = f"{prefix}{child.name}"
                out.append((f"{where}:{name} (line {child.lineno})", fingerprint_code(child)))
                visit(child, name + ".")
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            else:
                visit(child, prefix)

    visit(tree, "")
    return out


def shipped_folders(root: Path = KIT_ROOT) -> list[Path]:
    """The package folders the release ships (core.shipping, through kit.release)."""
    return [Path(root) / p for p in release_packages(root)]


def shipped_notebooks(root: Path = KIT_ROOT) -> list[Path]:
    return sorted(Path(root).glob(STUDENT_NOTEBOOKS))


def _notebook_sources(path: Path) -> list[str]:
    out = []
    for cell in nbformat.read(path, as_version=4).cells:
        if cell.cell_type == "code":
            # magics and shell lines blanked, as the review reads a notebook
            out.append("\n".join("" if line.lstrip().startswith(("%", "!")) else line
                                 for line in cell.source.split("\n")))
    return out


def shipped_functions(folders=None, notebooks=None) -> list[tuple[str, Fingerprints]]:
    folders = shipped_folders() if folders is None else folders
    notebooks = shipped_notebooks() if notebooks is None else notebooks
    out = []
    for folder in folders:
        for path in sorted(Path(folder).rglob("*.py")):
            if "__pycache__" not in path.parts:
                out += _functions(ast.parse(path.read_text(encoding="utf-8")), str(path.relative_to(folder.parent)))
    for path in notebooks:
        for k, src in enumerate(_notebook_sources(path), start=1):
            try:
                tree = ast.parse(src)
            except SyntaxError:
                continue
            out += _functions(tree, f"notebooks/{path.name}, cell {k}")
    return out


def reference_functions(solutions_dir: Path = SOLUTIONS) -> list[tuple[str, Fingerprints]]:
    """Every function of solutions/ (all of it answers, or serves answering, a graded question)."""
    out = []
    for path in sorted(Path(solutions_dir).glob("*.py")):
        out += _functions(ast.parse(path.read_text(encoding="utf-8")), f"solutions/{path.name}")
    return out


def alike_pairs(shipped, references) -> list[tuple[float, str, str, float]]:
    """(score, shipped function, reference function, shared) of every pair the review would flag,
    best first: one ``compare_function`` over both sides, read where a shipped function meets a
    reference one."""
    shipped = [(n, f) for n, f in shipped if f.hashes]
    references = [(n, f) for n, f in references if f.hashes]
    comp = compare_function("leak", shipped + references)
    ns = len(shipped)
    block = comp.score[:ns, ns:]
    found = [(float(block[i, j]), comp.names[i], comp.names[ns + j], float(comp.shared[i, ns + j]))
             for i, j in zip(*np.nonzero(block >= FLAG))]
    return sorted(found, reverse=True)


def release_score(reference: Fingerprints, given: set) -> tuple[float, int]:
    """(score, shared): the review's score of ``reference`` against the release read as one
    submission (the plain hashes ``given``); the release is far larger, so containment is the
    share of the reference's fingerprints that the release holds."""
    shared = sum(1 for h, _ in reference.hashes if h in given)
    if not reference.hashes:
        return 0.0, 0
    containment = shared / len(reference.hashes)
    return max(0.0, containment - CONTAINMENT_DISCOUNT) * min(1.0, shared / MIN_SHARED), shared


def graded_references(solutions_dir: Path = SOLUTIONS) -> dict[str, Fingerprints]:
    """The reference definition of every graded function (core.manifest), by name."""
    out = {}
    for path in sorted(Path(solutions_dir).glob("*.py")):
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name in GRADED:
                out[node.name] = fingerprint_code(node)
    return out


def release_given(folders=None, notebooks=None) -> set:
    """The plain hashes of what ships, computed as the review computes the handout's (given_hashes)."""
    folders = shipped_folders() if folders is None else folders
    notebooks = shipped_notebooks() if notebooks is None else notebooks
    given = given_hashes(None, folders)
    for path in notebooks:
        for src in _notebook_sources(path):
            given |= code_hashes(src)
    return given


# ------------------------------------------------------------------------------------------ tests


@pytest.fixture(scope="module")
def shipped():
    return shipped_functions()


def test_the_leak_scan_reads_every_shipped_package_and_notebook(shipped):
    assert {f.name for f in shipped_folders()} >= {"core", "scenes", "starter", "judging", "handin"}
    assert len(shipped_notebooks()) >= 7
    where = {n.split(":")[0].split("/")[0] for n, _ in shipped}
    assert {"core", "scenes", "starter", "judging", "handin", "notebooks"} <= where, where
    assert set(graded_references()) == set(GRADED)


def test_no_shipped_function_is_alike_to_a_reference_function_leak(shipped):
    found = alike_pairs(shipped, reference_functions())
    assert found == [], "\n".join(f"{s:.2f} ({sh:.0f} shared): {a} ~ {b}" for s, a, b, sh in found)


@functools.cache  # the same for every caller of the run: read, never changed
def graded_answers() -> dict[str, Fingerprints]:
    """Each graded reference less the hashes of the student notebooks (the stubs give those)."""
    stubs = given_hashes(NOTEBOOKS_DIR, ())
    return {name: fp.without(stubs) for name, fp in graded_references().items()}


def release_flags(given: set) -> dict[str, tuple[float, int, int]]:
    """name -> (score, shared, size) of every graded answer the packages ``given`` hold at FLAG or above."""
    out = {}
    for name, fp in graded_answers().items():
        score, shared = release_score(fp, given)
        if score >= FLAG:
            out[name] = (score, shared, len(fp.hashes))
    return out


@pytest.fixture(scope="module")
def released() -> set:
    """The plain hashes of the shipped packages (``release_given`` without the notebooks), made once
    for the module: fingerprinting every shipped file is the costly part of these tests."""
    return release_given(notebooks=[])


def test_no_graded_answer_is_held_by_the_release_as_a_whole_leak(released):
    flagged = release_flags(released)
    assert flagged == {}, "\n".join(f"{n}: score {s:.2f}, {sh} of its {size} fingerprints ship"
                                    for n, (s, sh, size) in flagged.items())


def test_the_leak_scan_finds_a_reference_rewritten_into_helpers(tmp_path, released):
    """The twisted-pair case's linear triangulation as it once shipped (starter/checks): renamed,
    cut into helpers, none the reference alone; both readings find it."""
    pkg = tmp_path / "starter"
    pkg.mkdir()
    (pkg / "helpers.py").write_text('''
import numpy as np


def _stack(P, a, Q, b):
    return np.stack([a[:, :1] * P[2] - P[0], a[:, 1:] * P[2] - P[1],
                     b[:, :1] * Q[2] - Q[0], b[:, 1:] * Q[2] - Q[1]], axis=1)


def _last(M):
    V = np.linalg.svd(M)[2][:, -1, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        return V[:, :3] / V[:, 3:]


def lift(P, a, Q, b):
    M = _stack(P, a, Q, b)
    return _last(M / np.linalg.norm(M, axis=2, keepdims=True))
''')
    found = alike_pairs(shipped_functions([pkg], []), reference_functions())
    assert any("_stack" in a and b.startswith("solutions/triangulation.py:triangulate") for _, a, b, _ in found), found
    # the release with the planted package: release_given is a union over files, so the shipped
    # packages' hashes plus the planted file's are release_given([*shipped_folders(), pkg], [])
    assert "triangulate" in release_flags(released | release_given([pkg], []))
