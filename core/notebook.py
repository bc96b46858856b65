"""Reading a homework notebook without running it: its code cells, and the statements that define things.

One reader for everything that looks into a student's notebook: the grader (which code to load
in the sandbox), ``from_notebook`` (a later notebook loading an earlier one's functions), the
code zip and the PDF cover (what looks answered), and the release check (no answer leaks).

A notebook is an ``.ipynb`` file or a ``.py`` file (``# %%`` lines split it into cells, as in
the percent format of Jupytext, VS Code and Spyder), given as bytes or text.  Reading it:

1. :func:`code_cells` gives its code cells, each with its 1-based position among all cells
   (markdown included, as the student counts them);
2. :func:`python_text` turns IPython syntax into Python: a cell magic other than the few whose
   body is Python (``%%time`` ...) makes the cell not Python at all; line magics, shell escapes
   (``!pip``, ``x = !ls``) and help requests (``np.linalg.svd?``) become ``pass`` at their
   indent, so line numbers stay those of the cell;
3. :func:`parse_cells` parses every cell; a cell with a syntax error is reported as a
   :class:`CellProblem` (data, never an exception) and the other cells still count;
4. :func:`definitions` keeps the statements that define things (:func:`is_definition`, one rule
   set for every caller).

:func:`notebook_stem` reads the stem the kit's builder writes into each notebook's metadata, so a
file that Colab or a browser renamed ("Copy of q2_eightpoint.ipynb", "q2_eightpoint (1).ipynb")
is still recognised.  Nothing here imports IPython or any kit package.
"""

from __future__ import annotations

import ast
import builtins
import json
import os
import re
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

__all__ = [
    "METADATA_KEY",
    "Cell",
    "CellProblem",
    "Definition",
    "NotebookUnreadable",
    "ParsedCell",
    "code_cells",
    "definitions",
    "find_notebook",
    "is_definition",
    "notebook_json",
    "notebook_stem",
    "parse_cells",
    "python_cells",
    "python_text",
    "read_text",
]

# The metadata key under which the kit's builder records a notebook's stem, variant and settings.
METADATA_KEY = "hw4_kit"

# Cell magics whose body is ordinary Python that a notebook would run.
PYTHON_CELL_MAGICS = frozenset({"time", "timeit", "capture", "prun", "debug"})

# Calls that read files, draw or save: never run while loading definitions.
SIDE_EFFECT_CALLS = frozenset({
    "load", "loadtxt", "genfromtxt", "fromfile", "imread", "open", "read", "read_csv", "save",
    "savez", "savetxt", "savefig", "show", "figure", "subplots", "plot", "scatter", "imshow",
    "system", "run", "Popen", "seed", "urlopen", "get", "post", "input", "print", "eval", "exec",
    "compile", "__import__", "sleep",
})

# Calls that run the homework rather than define it: the notebooks' self-checks (check_*), the
# stub-tolerant runner and the loaders of other notebooks.  An assignment whose value calls one of
# these, or a homework function, is a result, not a definition.
RUNNER_CALLS = frozenset({"try_run", "from_notebook", "notebook_definitions"})
LINK_CALLS = frozenset({"from_notebook"})


class NotebookUnreadable(ValueError):
    """The file is not a notebook that can be read (not UTF-8, not JSON, no list of cells)."""


@dataclass(frozen=True)
class Cell:
    """One code cell: ``number`` its 1-based position among all cells, ``source`` its text as
    saved, ``first_line`` the line of its first line in its file (1 for a notebook cell; for a
    .py file split in cells, where the cell starts)."""

    number: int
    source: str
    first_line: int = 1


@dataclass(frozen=True)
class CellProblem:
    """A code cell that could not be parsed: its 1-based cell number, the line (in the file's
    numbering, None when unknown) and the reason ("syntax error: ...")."""

    cell: int
    line: int | None
    message: str


@dataclass(frozen=True)
class ParsedCell:
    """A code cell as Python: ``text`` (magics turned into ``pass``) and its ``tree``."""

    cell: Cell
    text: str
    tree: ast.Module = field(compare=False, repr=False)


@dataclass(frozen=True)
class Definition:
    """One kept top-level statement.

    cell: the cell it comes from; line: line of its first line (decorators included) in the
    file's numbering; lineno: line of the statement itself (after its decorators); source: its
    text; defines: the names it binds, in a stable order; future: ``__future__`` features it
    imports; node: the parsed statement; cell_text: the Python text of its cell (for tracebacks).
    """

    cell: Cell
    line: int
    lineno: int
    source: str
    defines: tuple[str, ...]
    future: tuple[str, ...] = ()
    node: ast.stmt | None = field(default=None, compare=False, repr=False)
    cell_text: str = field(default="", compare=False, repr=False)


# ------------------------------------------------------------------------------------ files


def read_text(data: bytes | str) -> str:
    """``data`` as text (UTF-8, a byte-order mark dropped); NotebookUnreadable when it is not UTF-8."""
    if isinstance(data, str):
        return data
    try:
        return bytes(data).decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise NotebookUnreadable(f"it is not UTF-8 text ({exc.reason} at byte {exc.start})") from None


def notebook_json(data: bytes | str | dict) -> dict:
    """The notebook's JSON as a dict; NotebookUnreadable when it is not JSON or not an object."""
    if isinstance(data, dict):
        return data
    try:
        raw = json.loads(read_text(data))
    except (ValueError, RecursionError) as exc:
        if isinstance(exc, NotebookUnreadable):
            raise
        raise NotebookUnreadable(f"it is not valid JSON ({str(exc)[:120]})") from None
    if not isinstance(raw, dict):
        raise NotebookUnreadable("it is JSON but not a notebook")
    return raw


def notebook_stem(data: bytes | str | dict) -> str | None:
    """The stem the kit's builder recorded in the notebook's metadata (``metadata.hw4_kit.stem``),
    or None when there is none or the file is not a readable notebook.  ``data``: the file's
    bytes or text, or the notebook as a dict (an nbformat NotebookNode is one)."""
    try:
        raw = notebook_json(data)
    except NotebookUnreadable:
        return None
    meta = raw.get("metadata")
    kit = meta.get(METADATA_KEY) if isinstance(meta, dict) else None
    stem = kit.get("stem") if isinstance(kit, dict) else None
    return stem if isinstance(stem, str) and stem.isidentifier() else None


def find_notebook(folder: str | os.PathLike, stem: str) -> Path | None:
    """The notebook for ``stem`` in ``folder``: ``<stem>.ipynb`` when it exists, else the one
    notebook whose metadata names ``stem`` (a copy Colab or a browser renamed), else None.
    With several renamed copies, the most recently saved one is taken."""
    folder = Path(folder)
    exact = folder / f"{stem}.ipynb"
    if exact.is_file():
        return exact
    found = []
    for path in folder.glob("*.ipynb") if folder.is_dir() else ():
        try:
            if path.is_file() and notebook_stem(path.read_bytes()) == stem:
                found.append(path)
        except OSError:
            continue
    return max(found, key=lambda p: (p.stat().st_mtime, p.name)) if found else None


def code_cells(data: bytes | str | dict, *, python_file: bool = False) -> list[Cell]:
    """The code cells of a notebook (``python_file=False``) or of a .py file split at ``# %%`` lines.

    Raises NotebookUnreadable (a ValueError) when the file is not UTF-8, not JSON, or has no
    list of cells.
    """
    if python_file:
        lines = read_text(data).splitlines(keepends=True)
        starts = [0] + [i for i, line in enumerate(lines) if i > 0 and re.match(r"#\s?%%", line)]
        return [Cell(k, "".join(lines[a:b]), a + 1)
                for k, (a, b) in enumerate(zip(starts, starts[1:] + [len(lines)]), start=1)]
    raw = notebook_json(data)
    cells = raw.get("cells")
    if raw.get("nbformat", 4) != 4 and not isinstance(cells, list):
        # An old notebook (worksheets): let nbformat convert it.
        try:
            import nbformat

            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # missing cell ids and similar schema nits do not matter
                cells = nbformat.convert(nbformat.from_dict(raw), 4).get("cells")
        except Exception:  # noqa: BLE001 - nbformat raises many kinds; the check below reports it
            cells = None
    if not isinstance(cells, list):
        raise NotebookUnreadable("it is JSON but has no list of cells")
    out = []
    for k, cell in enumerate(cells, start=1):
        if not isinstance(cell, dict) or cell.get("cell_type") != "code":
            continue
        source = cell.get("source", "")
        if isinstance(source, list):
            source = "".join(s for s in source if isinstance(s, str))
        if isinstance(source, str):
            out.append(Cell(k, source))
    return out


# ------------------------------------------------------------------------------------ cells


def python_text(source: str) -> str | None:
    """The cell's Python text, or None for a cell in another language (``%%bash`` ...).

    Text that parses as it is comes back unchanged; otherwise line magics, shell escapes and help
    requests become ``pass`` at their indent.  A magic line of a Python cell magic (``%%time``) is
    blanked, not removed, so line numbers stay those of the cell.
    """
    first = source.lstrip().split("\n", 1)[0]
    if first.startswith("%%"):
        magic = first[2:].split(maxsplit=1)[0] if first[2:].strip() else ""
        if magic not in PYTHON_CELL_MAGICS:
            return None
        before, _, rest = source.partition(first)
        source = before + rest
    try:
        ast.parse(source)
        return source
    except SyntaxError:
        pass
    out = []
    for line in source.split("\n"):
        body = line.strip()
        if (body.startswith(("%", "!")) or re.match(r"[\w.]+\s*=\s*[%!]", body)
                or (body.startswith("?") or re.fullmatch(r"[\w.\[\]()'\"]+\?\??", body))):
            out.append(line[: len(line) - len(line.lstrip())] + "pass")
        else:
            out.append(line)
    return "\n".join(out)


def parse_cells(cells: Iterable[Cell | str]) -> tuple[list[ParsedCell], list[CellProblem]]:
    """Parse each code cell (strings are numbered 1, 2, ...): (parsed cells, problems).

    A cell in another language is left out silently; a cell with a syntax error is left out and
    reported, its line in the file's numbering.
    """
    parsed, problems = [], []
    for k, cell in enumerate(cells, start=1):
        if isinstance(cell, str):
            cell = Cell(k, cell)
        text = python_text(cell.source)
        if text is None:
            continue
        try:
            tree = ast.parse(text)
        except SyntaxError as exc:
            line = exc.lineno + cell.first_line - 1 if exc.lineno else None
            problems.append(CellProblem(cell.number, line, f"syntax error: {exc.msg}"))
            continue
        parsed.append(ParsedCell(cell, text, tree))
    return parsed, problems


def python_cells(data: bytes | str | dict, *, python_file: bool = False
                 ) -> tuple[list[ParsedCell], list[CellProblem]]:
    """:func:`code_cells` then :func:`parse_cells`."""
    return parse_cells(code_cells(data, python_file=python_file))


# ------------------------------------------------------------------------------ definitions


def definitions(cells: Iterable[ParsedCell], *, constants: bool = True, links: bool = False,
                homework: Iterable[str] = ()) -> list[Definition]:
    """The defining statements of the parsed cells, in notebook order (see :func:`is_definition`).

    constants: keep simple constant assignments (the grader does, as each statement runs on its
    own there and a failing one costs nothing; ``from_notebook`` does not, so loading an earlier
    notebook never reads data);
    links: keep ``name = from_notebook(...)`` lines (``from_notebook``, to follow a chain of
    notebooks; the grader loads every notebook itself, so it does not);
    homework: the homework's function names; an assignment that calls one is a result.
    """
    known = set(dir(builtins))
    homework = frozenset(homework)
    out = []
    for pc in cells:
        for node in pc.tree.body:
            if not is_definition(node, known, constants=constants, links=links, homework=homework):
                continue
            names = bound_names(node)
            known.update(names)
            offset = pc.cell.first_line - 1
            out.append(Definition(
                cell=pc.cell, line=_first_line(node) + offset, lineno=node.lineno + offset,
                source=_segment(pc.text, node), defines=tuple(sorted(names)),
                future=_future_features(node), node=node, cell_text=pc.text))
    return out


def is_definition(node: ast.stmt, known: set[str], *, constants: bool = True, links: bool = False,
                  homework: frozenset[str] = frozenset()) -> bool:
    """True for a top-level statement that defines things, in the one rule set of the kit.

    Kept: imports; ``def`` and ``class`` blocks; ``try`` blocks made only of kept statements and
    ``pass`` (the optional-import fallback ``try: import cv2`` / ``except ImportError: cv2 =
    None``); with ``links``, ``name = from_notebook(...)``; with ``constants``, assignments to
    plain names of a simple value: literals, names already ``known``, and calls of known functions
    that neither read, draw or save (:data:`SIDE_EFFECT_CALLS`) nor run the homework (a function
    of ``homework``, a ``check_*`` self-check, :data:`RUNNER_CALLS`).
    """
    if isinstance(node, (ast.Import, ast.ImportFrom, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
        return True
    if isinstance(node, ast.Assign):
        if not all(_is_name_target(t) for t in node.targets):
            return False
        if _is_link(node.value):
            return links
        return constants and _is_simple(node.value, known) and not _runs_homework(node.value, homework)
    if isinstance(node, ast.AnnAssign):
        if not isinstance(node.target, ast.Name):
            return False
        if node.value is None:
            return constants
        if _is_link(node.value):
            return links
        return constants and _is_simple(node.value, known) and not _runs_homework(node.value, homework)
    if isinstance(node, ast.Try):
        inner = node.body + node.orelse + node.finalbody + [s for h in node.handlers for s in h.body]
        inside = known | bound_names(node)
        return all(isinstance(s, ast.Pass) or is_definition(s, inside, constants=True, links=links,
                                                             homework=homework) for s in inner)
    return False


def bound_names(node: ast.stmt) -> set[str]:
    """The names a top-level statement binds (for an import, the top-level module name)."""
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
        return {node.name}
    if isinstance(node, (ast.Import, ast.ImportFrom)):
        return {(a.asname or a.name).split(".")[0] for a in node.names if a.name != "*"}
    if isinstance(node, ast.Assign):
        return {n.id for t in node.targets for n in ast.walk(t) if isinstance(n, ast.Name)}
    if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
        return {node.target.id}
    if isinstance(node, ast.Try):
        inner = node.body + node.orelse + node.finalbody + [s for h in node.handlers for s in h.body]
        return set().union(*(bound_names(s) for s in inner)) if inner else set()
    return set()


def _call_name(call: ast.Call) -> str | None:
    f = call.func
    return f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)


def _is_link(value: ast.expr) -> bool:
    return isinstance(value, ast.Call) and _call_name(value) in LINK_CALLS


def _runs_homework(value: ast.expr, homework: frozenset[str]) -> bool:
    """A value that calls something and names a homework function, a runner or a self-check."""
    if not any(isinstance(n, ast.Call) for n in ast.walk(value)):
        return False
    names = {n.id for n in ast.walk(value) if isinstance(n, ast.Name)}
    return bool(names & (homework | RUNNER_CALLS)) or any(n.startswith("check_") for n in names)


def _is_name_target(t: ast.expr) -> bool:
    if isinstance(t, ast.Name):
        return True
    return isinstance(t, (ast.Tuple, ast.List)) and all(_is_name_target(e) for e in t.elts)


def _is_simple(e: ast.expr, known: set[str]) -> bool:
    """A cheap expression made of literals, known names and calls of library functions on them."""
    if isinstance(e, ast.Constant):
        return True
    if isinstance(e, ast.Name):
        return e.id in known
    if isinstance(e, ast.Attribute):
        return _is_simple(e.value, known)
    if isinstance(e, (ast.Tuple, ast.List, ast.Set)):
        return all(_is_simple(x, known) for x in e.elts)
    if isinstance(e, ast.Dict):
        return all(k is None or _is_simple(k, known) for k in e.keys) and all(_is_simple(v, known) for v in e.values)
    if isinstance(e, ast.UnaryOp):
        return _is_simple(e.operand, known)
    if isinstance(e, ast.BinOp):
        return _is_simple(e.left, known) and _is_simple(e.right, known)
    if isinstance(e, ast.BoolOp):
        return all(_is_simple(v, known) for v in e.values)
    if isinstance(e, ast.Compare):
        return _is_simple(e.left, known) and all(_is_simple(c, known) for c in e.comparators)
    if isinstance(e, ast.Lambda):
        return all(_is_simple(d, known) for d in e.args.defaults + [d for d in e.args.kw_defaults if d])
    if isinstance(e, ast.Call):
        name = _call_name(e)
        return (name is not None and name not in SIDE_EFFECT_CALLS and _is_simple(e.func, known)
                and all(_is_simple(a.value if isinstance(a, ast.Starred) else a, known) for a in e.args)
                and all(_is_simple(k.value, known) for k in e.keywords))
    return False


def _first_line(node: ast.stmt) -> int:
    decorators = getattr(node, "decorator_list", [])
    return min([node.lineno] + [d.lineno for d in decorators])


def _segment(text: str, node: ast.stmt) -> str:
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef, ast.Try)):
        # A compound statement owns whole lines (nothing can precede it on its first line or
        # follow it on its last), and whole lines keep its decorators.
        lines = text.split("\n")
        return "\n".join(lines[_first_line(node) - 1: node.end_lineno])
    return ast.get_source_segment(text, node) or ast.unparse(node)


def _future_features(node: ast.stmt) -> tuple[str, ...]:
    if isinstance(node, ast.ImportFrom) and node.module == "__future__":
        return tuple(a.name for a in node.names)
    return ()
