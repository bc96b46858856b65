"""Step 3 of the notebook build: each block kind of a source -> the cells of one version
(student, key or nbgrader), with nbgrader's metadata and the sharing of a question's points."""

from __future__ import annotations

import ast
import textwrap
from dataclasses import dataclass, field
from pathlib import Path

import nbformat

from core.manifest import QUESTIONS, Question

from handin.html import KIT_CELL_TAG, PAGE_START_TAG, PLUMBING_TAG

from .setup import Settings, colab_text, setup_text
from .source import BARE_HEADING, Block, Extracted, SourceError, heading_text, referenced_names, extract_function

# Exactly what nbgrader's ClearSolutions writes, so its release of our nbgrader source and our
# student notebooks hold the same code.
NBGRADER_STUB = "# YOUR CODE HERE\nraise NotImplementedError()"
ANSWER_PLACEHOLDER = "YOUR ANSWER HERE"
BEGIN, END = "### BEGIN SOLUTION", "### END SOLUTION"


# ------------------------------------------------------------------- step 3: blocks -> cells


def markdown_cell(text: str, **meta) -> nbformat.NotebookNode:
    return nbformat.v4.new_markdown_cell(text, metadata=meta or {})


def _code(text: str, **meta) -> nbformat.NotebookNode:
    return nbformat.v4.new_code_cell(text, metadata=meta or {})


def clear_regions(text: str, variant: str, where: str) -> tuple[str, bool]:
    """Apply nbgrader solution markers for one version; returns (text, had_markers)."""
    out, inside, found, indent = [], False, False, ""
    for line in text.splitlines():
        marker = line.strip()
        if marker == BEGIN:
            if inside:
                raise SourceError(f"{where}: {BEGIN} inside another solution region")
            inside, found, indent = True, True, line[:len(line) - len(line.lstrip())]
            if variant == "nbgrader":
                out.append(line)
            elif variant == "student":
                out += [indent + s for s in NBGRADER_STUB.splitlines()]
            continue
        if marker == END:
            if not inside:
                raise SourceError(f"{where}: {END} without {BEGIN}")
            inside = False
            if variant == "nbgrader":
                out.append(line)
            continue
        if not inside or variant != "student":
            out.append(line)
    if inside:
        raise SourceError(f"{where}: {BEGIN} is never closed")
    return "\n".join(out), found


def solution_text(ext: Extracted, variant: str, emitted_helpers: set[str]) -> str:
    if variant == "student":
        return ext.contract + "\n" + textwrap.indent(NBGRADER_STUB, "    ")
    if variant == "key":
        new = [(n, s) for n, s in ext.helpers if n not in emitted_helpers]
        emitted_helpers.update(n for n, _ in new)
        names, dotted = referenced_names([ast.parse(ext.source)] + [ast.parse(s) for _, s in new])
        imports = [stmt for stmt in ext.imports if _binds_used(stmt, names, dotted)]
        parts = ["\n".join(imports)] if imports else []
        parts += [s for _, s in new] + [ext.source]
        return "\n\n\n".join(parts)
    # nbgrader: the helpers and imports the body needs go inside the region, nested in the
    # function, because nbgrader turns a region into a stub that must still run.
    # The kit's keyword-only switches are bound to their defaults: the def is the handout's.
    inner = (["\n".join(ext.switches)] if ext.switches else []) \
        + (["\n".join(ext.imports)] if ext.imports else []) \
        + [s for _, s in ext.helpers] + [textwrap.dedent(ext.body)]
    region = "\n\n".join(textwrap.indent(p, "    ") for p in inner)
    return f"{ext.contract}\n    {BEGIN}\n{region}\n    {END}"


def _binds_used(stmt: str, names: set[str], dotted: set[str]) -> bool:
    node = ast.parse(stmt).body[0]
    if isinstance(node, ast.Import):
        return any((a.asname or a.name) in (names | dotted) for a in node.names)
    return any((a.asname or a.name) in names for a in node.names)


def _check_text(name: str, module: str, variant: str) -> str:
    # The check prints its report (plain text survives the PDF) and reports a stub as "not
    # implemented yet" itself; assigning the report keeps Jupyter from showing it twice.
    text = f"from starter.checks.{module} import check_{name}\n\nreport = check_{name}({name})"
    if variant == "nbgrader":
        # nbgrader fails a test cell that raises.
        text += f"\nassert report.passed, \"the public checks of {name} do not all pass\""
    return text


def _nbgrader_meta(grade_id: str, *, solution: bool, grade: bool, locked: bool, points: int | None = None) -> dict:
    meta = {"grade": grade, "grade_id": grade_id, "locked": locked, "schema_version": 3,
            "solution": solution, "task": False}
    if grade:
        meta["points"] = points
    return {"nbgrader": meta}


# ------------------------------------------------------------------------ step 4: assemble


@dataclass
class BuildState:
    """What the builder knows while it walks one notebook's blocks."""

    stem: str
    variant: str
    settings: Settings
    solutions_dir: Path
    question: Question | None = None
    defined: set[str] = field(default_factory=set)        # names bound by earlier code cells
    emitted_helpers: set[str] = field(default_factory=set)
    graded: dict[str, list] = field(default_factory=dict)  # qid -> [(cell, explicit points or None)]
    seen_questions: list[str] = field(default_factory=list)
    solutions: list[str] = field(default_factory=list)
    setup_seen: bool = False
    code_cells: int = 0


def _bound_names(text: str, where: str) -> set[str]:
    try:
        tree = ast.parse(text)
    except SyntaxError as exc:
        raise SourceError(f"{where}: code does not parse (line {exc.lineno}: {exc.msg})") from None
    out = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out.add(node.name)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            out.update((a.asname or a.name).split(".")[0] for a in node.names)
        else:
            out.update(n.id for n in ast.walk(node) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store))
    return out


def _markdown_block(block: Block, st: BuildState, where: str) -> list[nbformat.NotebookNode]:
    m = BARE_HEADING.match(block.text.splitlines()[0])
    if not m:
        tags = [{"page": PAGE_START_TAG, "plumbing": PLUMBING_TAG}[a] for a in block.args]
        return [markdown_cell(block.text, tags=tags)] if tags else [markdown_cell(block.text)]
    hashes, qid = m.groups()
    q = next((q for q in QUESTIONS if q.id == qid), None)
    if q is None or q.notebook != st.stem:
        raise SourceError(f"{where}: heading {qid} is not a question of {st.stem} in core.manifest")
    if qid in st.seen_questions:
        raise SourceError(f"{where}: heading {qid} appears twice")
    st.question = q
    st.seen_questions.append(qid)
    rest = block.text.split("\n", 1)[1] if "\n" in block.text else ""
    return [markdown_cell(heading_text(q, hashes) + ("\n" + rest if rest else ""))]


def _colab_block(block: Block, st: BuildState, where: str) -> list[nbformat.NotebookNode]:
    return [markdown_cell(colab_text(st.stem, st.settings), tags=[PLUMBING_TAG])]


def _setup_block(block: Block, st: BuildState, where: str) -> list[nbformat.NotebookNode]:
    if st.code_cells:
        raise SourceError(f"{where}: the setup cell must be the first code cell")
    st.setup_seen = True
    return [_code(setup_text(st.settings), tags=[PLUMBING_TAG])]


# The context manager the setup cell defines (kit/notebooks/setup.py): the kit's own cells run inside it.
KIT_CELL = "kit_cell"


def _is_definition(node: ast.stmt) -> bool:
    """An import, a def or class, or ``name = from_notebook(...)``: what ``from_notebook`` loads of a notebook."""
    if isinstance(node, (ast.Import, ast.ImportFrom, ast.FunctionDef, ast.ClassDef)):
        return True
    return (isinstance(node, ast.Assign) and isinstance(node.value, ast.Call)
            and isinstance(node.value.func, ast.Name) and node.value.func.id == "from_notebook")


def _contained(text: str, label: str, where: str) -> str:
    """A cell of the kit with what follows its leading imports inside ``with kit_cell(label):``, so
    that whatever the student's functions return, a failure prints one line and later cells run.

    A cell of definitions only (imports, defs, ``from_notebook`` lines: what later notebooks load
    of it) or of comments only stays as it is."""
    body = ast.parse(text).body
    k = 0
    while k < len(body) and isinstance(body[k], (ast.Import, ast.ImportFrom)):
        k += 1
    if all(_is_definition(node) for node in body[k:]):
        return text
    lines = text.splitlines()
    cut = body[k].lineno - 1
    while cut > 0 and lines[cut - 1].lstrip().startswith("#"):  # a comment stays with its statement
        cut -= 1
    head = "\n".join(lines[:cut]).rstrip("\n")
    inside = "\n".join(("    " + line) if line.strip() else "" for line in lines[cut:])
    out = (head + "\n\n" if head else "") + f'with {KIT_CELL}("{label}"):\n{inside}'
    try:
        ast.parse(out)
    except SyntaxError as exc:
        raise SourceError(f"{where}: the cell cannot be put inside {KIT_CELL} ({exc.msg})") from None
    return out


def _python_block(block: Block, st: BuildState, where: str) -> list[nbformat.NotebookNode]:
    text, marked = clear_regions(block.text, st.variant, where)
    st.defined |= _bound_names(block.text.replace(BEGIN, "").replace(END, ""), where)
    tags = list(block.args)
    if not marked:  # the kit's own cell: contained, and tagged so that the PDF shows no path or traceback of it
        text = _contained(text, st.question.id if st.question else st.stem, where)
        tags.append(KIT_CELL_TAG)
    meta = {"tags": tags} if tags else {}
    if marked and st.variant == "nbgrader":
        meta.update(_nbgrader_meta(f"{st.stem}_cell{st.code_cells}", solution=True, grade=False, locked=False))
    return [_code(text, **meta)]


def _solution_block(block: Block, st: BuildState, where: str) -> list[nbformat.NotebookNode]:
    (name,) = _one_arg(block, where)
    if st.question is None or name not in st.question.functions:
        raise SourceError(f"{where}: {name} is not a function of the question above it "
                          f"({st.question.id if st.question else 'no question yet'})")
    ext = extract_function(name, st.solutions_dir)
    missing = [n for n in ext.needs if n not in st.defined]
    if missing:
        raise SourceError(f"{where}: {name} calls {missing}, which no earlier cell of {st.stem} defines "
                          "(add a solution cell, or a from_notebook line, before it)")
    st.defined.add(name)
    st.solutions.append(name)
    meta = _nbgrader_meta(name, solution=True, grade=False, locked=False) if st.variant == "nbgrader" else {}
    return [_code(solution_text(ext, st.variant, st.emitted_helpers), **meta)]


def _check_block(block: Block, st: BuildState, where: str) -> list[nbformat.NotebookNode]:
    (name,) = _one_arg(block, where)
    if name not in st.solutions:
        raise SourceError(f"{where}: check of {name} before (or without) its solution cell")
    module = extract_function(name, st.solutions_dir).module
    cell = _code(_check_text(name, module, st.variant), tags=[KIT_CELL_TAG])
    st.graded.setdefault(st.question.id, []).append((cell, f"check_{name}", None, False))
    return [cell]


def _answer_block(block: Block, st: BuildState, where: str) -> list[nbformat.NotebookNode]:
    qid, *opts = block.args or ("",)
    if st.question is None or qid != st.question.id:
        raise SourceError(f"{where}: answer for {qid!r} under the heading of "
                          f"{st.question.id if st.question else 'no question'}")
    if opts == ["ungraded"]:
        # Read from the PDF only: nbgrader has no ungraded markdown answer, so its source
        # gets the placeholder too (a plain cell there would hand the answer out).
        return [markdown_cell(block.text if st.variant == "key" else ANSWER_PLACEHOLDER)]
    points = _points_option(opts, where)
    cell = markdown_cell(ANSWER_PLACEHOLDER if st.variant == "student" else block.text)
    st.graded.setdefault(qid, []).append((cell, f"answer_{qid.replace('.', '_')}", points, True))
    return [cell]


# Block kind -> its builder.  The blocks after the setup cell (all but these three) must follow it,
# and each counts as a cell of the notebook's body (``st.code_cells``, used in nbgrader ids).
_BLOCKS = {
    "markdown": _markdown_block,
    "colab": _colab_block,
    "setup": _setup_block,
    "python": _python_block,
    "solution": _solution_block,
    "check": _check_block,
    "answer": _answer_block,
}
_BEFORE_SETUP = ("markdown", "colab", "setup")


def block_to_cells(block: Block, st: BuildState, where: str) -> list[nbformat.NotebookNode]:
    if block.kind not in _BLOCKS:
        raise SourceError(f"{where}: unknown block kind {block.kind!r} "
                          "(expected python, colab, setup, solution, check, answer)")
    if block.kind not in _BEFORE_SETUP:
        if not st.setup_seen:
            raise SourceError(f"{where}: a code cell comes before the {{setup}} cell")
        st.code_cells += 1
    cells = _BLOCKS[block.kind](block, st, where)
    if block.kind == "setup":
        st.code_cells += 1  # counted after its own check that it is the first
    return cells


def _one_arg(block: Block, where: str) -> tuple[str]:
    if len(block.args) != 1:
        raise SourceError(f"{where}: expected one function name after {{{block.kind}}}, got {list(block.args)}")
    return block.args


def _points_option(opts, where) -> int | None:
    points = None
    for opt in opts:
        key, _, value = opt.partition("=")
        if key != "points" or not value.isdigit():
            raise SourceError(f"{where}: expected an option points=N or ungraded, got {opt!r}")
        points = int(value)
    return points


def share_points(st: BuildState, name: str) -> None:
    """Give every graded cell its points; the question's total must come out exactly."""
    for qid, items in st.graded.items():
        q = next(q for q in QUESTIONS if q.id == qid)
        fixed = sum(p for _, _, p, _ in items if p is not None)
        free = [i for i, (_, _, p, _) in enumerate(items) if p is None]
        left = q.points - fixed
        if left < 0 or (free and left < len(free)) or (not free and left != 0):
            raise SourceError(f"{name}: the graded cells of {qid} cannot share its {q.points} points "
                              f"({fixed} given explicitly to {len(items) - len(free)} cell(s), {len(free)} left)")
        shares = {i: left // len(free) + (1 if k < left % len(free) else 0) for k, i in enumerate(free)}
        for i, (cell, grade_id, points, is_answer) in enumerate(items):
            pts = points if points is not None else shares[i]
            if st.variant == "nbgrader":
                cell.metadata.update(_nbgrader_meta(grade_id, solution=is_answer, grade=True,
                                                    locked=not is_answer, points=pts))
