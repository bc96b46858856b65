"""What a student is shown of a homework function states its contract, not the reference's method.

The student stubs (the student notebooks, and the nbgrader source once its solution regions are
cleared as nbgrader's release does) show the def line and the docstring of the reference in
solutions/, cut at the docstring's ``Method (answer key only)`` section; the answer key keeps it
all.  These tests hold that:

- every stub's signature is the handout's (the reference's keyword-only switches are not shown,
  and every other homework function has no extra parameter);
- every stub's docstring is the reference's contract, word for word;
- no stub, and no hint of the catalogue of known mistakes (judging.mistakes), contains a formula
  of the reference's method or one of its tuned constants: the numeric literals of the
  reference bodies and method sections.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import nbformat
import pytest

from core.manifest import QUESTIONS
from core.paths import KIT_ROOT
from judging.mistakes import KNOWN_MISTAKES
from kit import notebooks as nbk

ALL_FUNCTIONS = [f for q in QUESTIONS for f in q.functions]

# The handout's signatures (hw4 handout, "with the signature ..."); functions it names without a
# signature (findM2, compute3D_pts, plot_3d_keypoint_video) take the kit's, with no defaults.
HANDOUT_SIGNATURES = {
    "eightpoint": "pts1, pts2, M",
    "essentialMatrix": "F, K1, K2",
    "triangulate": "C1, pts1, C2, pts2",
    "epipolarCorrespondence": "im1, im2, F, x1, y1",
    "rodriguesResidual": "K1, M1, p1, K2, p2, x",
    "bundleAdjustment": "K1, M1, p1, K2, M2_init, p2, w_init",
    "MultiviewReconstruction": "C1, pts1, C2, pts2, C3, pts3, Thres",
}

# Pieces of the reference's methods that a stub or a hint must not give away (case-insensitive
# regular expressions).  The handout's own formulas (T^T F T, the residual layout, the error
# sum) are the question, not the answer, and are not listed.
FORMULAS = {
    "E from F": r"K2\s*\^\s*T|K2\.T\s*@|K2\s*\.T|K2'\s*\*?\s*F|transpose\(K2\)",
    "the SVD": r"\bsvd\b|singular vector|smallest singular value",
    "Levenberg-Marquardt": r"levenberg|marquardt",
    "scipy's solvers by name": r"least_squares|lstsq|method\s*=\s*['\"]lm",
    "the Gaussian's sigma": r"\bsigma\b",
    "the DLT rows": r"C\d?\[2\]|x\s*C\d?\[?2|\bDLT\b",
    "the gauge the reference holds": r"\|\s*t2?\s*\|\s*(?:is\s+)?held|held at its initial",
    "cheirality by name": r"cheirality",
    "the window and search names": r"_WINDOW|_SIGMA|_SEARCH",
}

# Numbers a contract may state although the reference's code uses them: the handout's "at least
# 8 points", and the shapes the handout defines: the residuals (4N,) and x (3N + 6,).
ALLOWED_NUMBERS = {0.0, 1.0, 2.0, 3.0, -1.0, 4.0, 6.0, 8.0}


# ------------------------------------------------------------------------- the reference side


def _reference(name: str) -> tuple[Path, ast.FunctionDef]:
    path = nbk.find_module(name, KIT_ROOT / "solutions")
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return path, next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == name)


def _method_section(doc: str) -> str:
    head, sep, tail = doc.partition(nbk.METHOD_SECTION)
    return tail if sep else ""


_NUMBER = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?(?:e-?\d+)?(?![\w.])", re.IGNORECASE)


def _numbers_in_text(text: str) -> set[float]:
    return {float(m) for m in _NUMBER.findall(text)}


def reference_constants() -> set[float]:
    """Numeric literals of every reference body (helpers and module constants too) and method section."""
    out: set[float] = set()
    for path in sorted((KIT_ROOT / "solutions").glob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        if not {n.name for n in tree.body if isinstance(n, ast.FunctionDef)} & set(ALL_FUNCTIONS):
            continue   # grader-side case builders (matching styles, the twisted pair): not an answer's method
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Module)):
                doc = ast.get_docstring(node, clean=False) if not isinstance(node, ast.Module) else None
                if doc:
                    out |= _numbers_in_text(_method_section(doc))
            if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
                    and not isinstance(node.value, bool):
                out.add(float(node.value))
            elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub) \
                    and isinstance(node.operand, ast.Constant) and isinstance(node.operand.value, (int, float)):
                out.add(-float(node.operand.value))
    # A docstring's own numbers are not code: only the method sections counted above.
    return out - ALLOWED_NUMBERS


def leaks_in(text: str, constants: set[float]) -> list[str]:
    """What of the reference's method ``text`` gives away: formula names and tuned constants."""
    found = [f"{what} ({m.group(0)!r})" for what, pattern in FORMULAS.items()
             for m in [re.search(pattern, text, flags=re.IGNORECASE)] if m]
    found += [f"the constant {n:g}" for n in sorted(_numbers_in_text(text) & constants)]
    return found


# ---------------------------------------------------------------------------- the student side


def _stubs_of(cells: list[str]) -> dict[str, str]:
    """Function name -> the source of its def (signature and docstring), for the homework functions."""
    out = {}
    for text in cells:
        tree = ast.parse(text)
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and node.name in ALL_FUNCTIONS:
                out[node.name] = ast.get_source_segment(text, node)
    return out


def student_stubs() -> dict[tuple[str, str], str]:
    """(where, name) -> the stub's source, in the student notebooks and the cleared nbgrader source."""
    out = {}
    for q in QUESTIONS:
        if not q.functions:
            continue
        for variant in ("student", "nbgrader"):
            nb = nbformat.read(nbk.output_path(q.notebook, variant), as_version=4)
            cells = [c.source for c in nb.cells if c.cell_type == "code"]
            if variant == "nbgrader":  # what nbgrader's release shows: each region becomes the stub
                cells = [nbk.clear_regions(c, "student", q.notebook)[0] for c in cells]
            for name, source in _stubs_of(cells).items():
                if name in q.functions:
                    out[(f"{q.notebook} ({variant})", name)] = source
    return out


STUBS = student_stubs()


def test_every_function_has_a_stub_in_both_student_versions():
    for name in ALL_FUNCTIONS:
        assert {w.split(" (")[1] for (w, n) in STUBS if n == name} == {"student)", "nbgrader)"}, name


@pytest.mark.parametrize("where, name", sorted(STUBS))
def test_stub_signature_is_the_handouts(where, name):
    stub = ast.parse(STUBS[(where, name)]).body[0]
    _, ref = _reference(name)
    args = ast.unparse(stub.args)
    if name in HANDOUT_SIGNATURES:
        assert args == HANDOUT_SIGNATURES[name]
    assert "=" not in args, f"{name}: a default in the stub's signature is a parameter the handout does not have"
    # The reference may add keyword-only switches for the kit's own use, never anything else.
    assert [a.arg for a in ref.args.args] == [a.arg for a in stub.args.args]
    assert not stub.args.kwonlyargs and stub.args.vararg is None and stub.args.kwarg is None


@pytest.mark.parametrize("where, name", sorted(STUBS))
def test_stub_docstring_is_the_references_contract(where, name):
    stub = ast.parse(STUBS[(where, name)]).body[0]
    _, ref = _reference(name)
    doc = ast.get_docstring(ref, clean=False)
    contract = doc.split(nbk.METHOD_SECTION)[0].rstrip() if nbk.METHOD_SECTION in doc else doc
    got = ast.get_docstring(stub, clean=False)
    assert got.rstrip() == contract.rstrip()
    assert nbk.METHOD_SECTION not in got


@pytest.mark.parametrize("where, name", sorted(STUBS))
def test_stub_gives_no_formula_or_tuned_constant_away(where, name):
    assert leaks_in(STUBS[(where, name)], reference_constants()) == []


@pytest.mark.parametrize("code", sorted(KNOWN_MISTAKES))
def test_mistake_hint_says_what_is_wrong_not_the_fix(code):
    name, hint = KNOWN_MISTAKES[code]
    assert leaks_in(f"{name}: {hint}", reference_constants()) == []


def test_the_answer_key_keeps_the_method():
    """The method sections are stripped for students only: the key shows the reference whole."""
    key = {}
    for q in QUESTIONS:
        if q.functions:
            nb = nbformat.read(nbk.output_path(q.notebook, "key"), as_version=4)
            key.update(_stubs_of([c.source for c in nb.cells if c.cell_type == "code"]))
    with_method = [n for n in ALL_FUNCTIONS if nbk.METHOD_SECTION in ast.get_docstring(_reference(n)[1])]
    assert {"eightpoint", "essentialMatrix", "triangulate", "epipolarCorrespondence",
            "bundleAdjustment"} <= set(with_method)
    for name in with_method:
        assert nbk.METHOD_SECTION in key[name]


def test_the_scan_finds_what_it_looks_for():
    constants = reference_constants()
    assert {15.0, 3.5, 40.0} <= constants  # the matcher's tuned window, sigma and search range
    assert leaks_in("E = K2^T F K1", constants)
    assert leaks_in("return K2.T @ F @ K1", constants)
    assert leaks_in("window : odd side (default 15)", constants)
    assert leaks_in("solve with np.linalg.svd", constants)
    assert leaks_in("Levenberg-Marquardt with |t2| held", constants)
    assert not leaks_in("F : (3, 3), x2^T F x1 = 0, N >= 8 points of image 1 and 2", constants)


def test_builder_cuts_the_method_and_the_switches(tmp_path):
    (tmp_path / "fundamental.py").write_text('''
def eightpoint(pts1, pts2, M, *, refine=True):
    """Contract line.

    Returns
    -------
    F : (3, 3)

    Method (answer key only)
    ------------------------
    The secret.
    """
    return refine
''')
    ext = nbk.extract_function("eightpoint", tmp_path)
    assert ext.contract.startswith("def eightpoint(pts1, pts2, M):\n")
    assert "secret" not in ext.contract and "Method" not in ext.contract
    assert ext.contract.endswith('F : (3, 3)\n    """')
    assert ext.switches == ("refine = True",)
    assert "secret" in ext.header
    nbgrader = nbk.solution_text(ext, "nbgrader", set())
    ns: dict = {}
    exec(nbgrader, ns)  # noqa: S102 - our own generated text
    assert ns["eightpoint"](1, 2, 3) is True
