"""Read a student's submission and find the code of each notebook, by parsing only (never running it).

A submission is a folder or a .zip of the per-question notebooks (``q2_eightpoint.ipynb`` ...), or
of ``.py`` files.  Files are matched to the manifest's notebooks by the question number in their
name (``q2``, ``Q2 eightpoint (1).ipynb``, ``hw4_q2.py``), wherever they sit in the tree.

From each notebook we keep what defines things, as if the notebook were run from top to bottom
but without its heavy or side-effecting statements: top-level imports, function and class
definitions, ``try`` blocks made only of those, and assignments of simple constants.  Each kept
statement becomes a ``SourceUnit`` that the sandbox executes on its own, so one failing import
does not lose the definitions after it; since units run in notebook order, the last definition
of a name wins.  A code cell with a syntax error is skipped whole and reported; a notebook that
is not valid JSON is reported as unreadable and the others are still used.
"""

from __future__ import annotations

import ast
import builtins
import json
import os
import re
import stat
import warnings
import zipfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

from core.manifest import NOTEBOOKS, functions_of_notebook

__all__ = [
    "CellProblem",
    "ParsedNotebook",
    "SizeLimits",
    "SourceUnit",
    "Submission",
    "SubmissionError",
    "load_submission",
    "parse_cells",
    "parse_notebook",
    "parse_python",
]


class SubmissionError(ValueError):
    """The submission as a whole cannot be used (unsafe archive, too large, not a folder or zip)."""


@dataclass(frozen=True)
class SizeLimits:
    """Bounds on what is read: bytes of one candidate file, bytes of all files (as declared
    by a zip or found in a folder), and number of entries."""

    max_file_bytes: int = 50 * 2**20
    max_total_bytes: int = 500 * 2**20
    max_entries: int = 5000


@dataclass(frozen=True)
class SourceUnit:
    """One kept top-level statement of a notebook, executed on its own in the sandbox.

    origin: where it comes from ("q2_eightpoint.ipynb, cell 4"), used as the code's file name so
    that error messages point the student to it; line: line of the statement's first line within
    that cell (1-based); source: the statement's text; future: ``__future__`` features it
    imports; defines: the names it binds.
    """

    origin: str
    line: int
    source: str
    future: tuple[str, ...] = ()
    defines: tuple[str, ...] = ()

    def to_job(self) -> dict:
        """The unit as the child reads it."""
        return {"origin": self.origin, "line": self.line, "source": self.source, "future": list(self.future)}


@dataclass(frozen=True)
class CellProblem:
    """A code cell that was skipped: its 1-based position among all cells, the line, the reason."""

    cell: int
    line: int | None
    message: str


@dataclass(frozen=True)
class ParsedNotebook:
    """What was found in one file of the submission.

    stem: the manifest's notebook stem it answers ("q2_eightpoint"); filename: its path inside the
    submission; readable: False when the file could not be read at all (``error`` says why);
    units: the kept statements in notebook order; syntax_errors: skipped cells;
    definitions: each bound name -> origin of its last (winning) definition;
    redefined: names bound more than once -> how many times; expected: the functions the
    manifest lists for this notebook.
    """

    stem: str
    filename: str
    readable: bool = True
    error: str | None = None
    units: tuple[SourceUnit, ...] = ()
    syntax_errors: tuple[CellProblem, ...] = ()
    definitions: dict[str, str] = field(default_factory=dict)
    redefined: dict[str, int] = field(default_factory=dict)
    expected: tuple[str, ...] = ()

    @property
    def missing(self) -> tuple[str, ...]:
        """Expected functions this notebook does not define."""
        return tuple(f for f in self.expected if f not in self.definitions)

    @property
    def source(self) -> str:
        """All kept statements as one program (for reading; the sandbox runs ``units``)."""
        return "\n\n".join(f"# {u.origin}, line {u.line}\n{u.source}" for u in self.units) + "\n"

    def diagnostics(self) -> list[str]:
        """Sentences for the student about this file (unreadable, syntax errors, redefinitions, missing)."""
        if not self.readable:
            return [f"{self.filename} could not be read: {self.error}. None of its code was used."]
        notes = []
        for p in self.syntax_errors:
            where = f" (line {p.line})" if p.line else ""
            notes.append(f"{self.filename}, cell {p.cell}: {p.message}{where}; the code of that cell was not used.")
        for name in self.expected:
            if name in self.redefined:
                notes.append(f"{self.filename}: {name} is defined {self.redefined[name]} times; "
                             f"the last one ({self.definitions[name]}) is used.")
        notes.extend(f"{self.filename}: {name} is not defined." for name in self.missing)
        return notes


@dataclass(frozen=True)
class Submission:
    """A parsed submission: one ParsedNotebook per manifest stem found.

    notebooks: stem -> ParsedNotebook; missing_notebooks: stems with no file; ignored: files not
    used, each with the reason.
    """

    name: str
    notebooks: dict[str, ParsedNotebook]
    missing_notebooks: tuple[str, ...] = ()
    ignored: tuple[str, ...] = ()

    def units_for(self, stem: str, *, borrow: bool = True) -> tuple[SourceUnit, ...]:
        """The code to load in the sandbox to test the functions of notebook ``stem``.

        With ``borrow`` the other notebooks' statements come first (in manifest order) and this
        notebook's last, so its own definitions win and a function written in the wrong notebook
        is still found.
        """
        if stem not in NOTEBOOKS:
            raise ValueError(f"stem: expected one of {list(NOTEBOOKS)}, got {stem!r}")
        own = self.notebooks[stem].units if stem in self.notebooks else ()
        if not borrow:
            return tuple(own)
        others = [u for s in NOTEBOOKS if s != stem and s in self.notebooks for u in self.notebooks[s].units]
        return tuple(others) + tuple(own)

    def where_defined(self, function: str, stem: str) -> str | None:
        """Origin of the definition of ``function`` that ``units_for(stem)`` would use, or None."""
        if stem in self.notebooks and function in self.notebooks[stem].definitions:
            return self.notebooks[stem].definitions[function]
        found = None
        for s in NOTEBOOKS:
            if s != stem and s in self.notebooks and function in self.notebooks[s].definitions:
                found = self.notebooks[s].definitions[function]
        return found

    def missing_functions(self, stem: str) -> tuple[str, ...]:
        """Functions the manifest expects from ``stem`` that no notebook of the submission defines."""
        return tuple(f for f in functions_of_notebook(stem) if self.where_defined(f, stem) is None)

    def diagnostics(self) -> list[str]:
        """Every note about the submission, in manifest order."""
        notes = []
        for stem in NOTEBOOKS:
            if stem in self.missing_notebooks:
                notes.append(f"No file for {stem} (expected a notebook whose name starts with {_qkey(stem)}).")
            elif stem in self.notebooks:
                nb = self.notebooks[stem]
                notes.extend(nb.diagnostics())
                for f in nb.missing:
                    elsewhere = self.where_defined(f, stem)
                    if elsewhere:
                        notes.append(f"{f} was found in {elsewhere} and is used from there.")
        notes.extend(f"Not used: {reason}" for reason in self.ignored)
        return notes


# ------------------------------------------------------------------------------------------------
# files


def load_submission(path: str | Path, *, stems: Sequence[str] = NOTEBOOKS,
                    limits: SizeLimits = SizeLimits()) -> Submission:
    """Read the submission at ``path`` (a folder or a .zip) and parse each notebook it holds.

    Parameters
    ----------
    path : str or Path
        A folder or a zip archive.  Hidden entries (starting with ".", such as
        ``.ipynb_checkpoints``) and ``__MACOSX`` are ignored; symbolic links are never followed.
    stems : sequence of str
        The notebook stems to look for (the manifest's by default).
    limits : SizeLimits
        Size bounds.

    Raises
    ------
    SubmissionError
        When ``path`` is neither a folder nor a zip, when the archive has an entry that would
        leave its folder (an absolute path or "..": a zip-slip attempt), or when it is too large.
    """
    path = Path(path)
    if path.is_dir() and not path.is_symlink():
        files = _folder_files(path, limits)
    elif path.is_file() and zipfile.is_zipfile(path):
        files = _zip_files(path, limits)
    else:
        raise SubmissionError(f"path: expected a folder or a .zip archive, got {str(path)!r}")

    by_stem: dict[str, list[tuple[str, bytes]]] = {}
    ignored: list[str] = []
    for name, data in files:
        stem = _stem_of(name, stems)
        if stem is None:
            ignored.append(f"{name} (its name does not start with a question number)")
        else:
            by_stem.setdefault(stem, []).append((name, data))

    notebooks: dict[str, ParsedNotebook] = {}
    for stem, candidates in by_stem.items():
        candidates.sort(key=lambda nd: _preference(nd[0], stem))
        name, data = candidates[0]
        ignored.extend(f"{other} (another file, {name}, was used for {stem})" for other, _ in candidates[1:])
        if name.lower().endswith(".py"):
            notebooks[stem] = parse_python(data, stem=stem, filename=name)
        else:
            notebooks[stem] = parse_notebook(data, stem=stem, filename=name)
    missing = tuple(s for s in stems if s not in notebooks)
    return Submission(path.name, notebooks, missing, tuple(ignored))


def _is_candidate(name: str) -> bool:
    parts = PurePosixPath(name).parts
    if any(p.startswith(".") or p == "__MACOSX" or p == "__pycache__" for p in parts):
        return False
    return name.lower().endswith((".ipynb", ".py"))


def _folder_files(root: Path, limits: SizeLimits) -> list[tuple[str, bytes]]:
    out, total, count = [], 0, 0
    for folder, dirs, names in os.walk(root, followlinks=False):
        dirs.sort()
        for name in sorted(names):
            count += 1
            if count > limits.max_entries:
                raise SubmissionError(f"path: expected at most {limits.max_entries} entries, got more")
            p = Path(folder, name)
            rel = p.relative_to(root).as_posix()
            st = p.lstat()  # lstat: a symbolic link is skipped, never followed
            if not stat.S_ISREG(st.st_mode) or not _is_candidate(rel):
                continue
            total += st.st_size
            if total > limits.max_total_bytes:
                raise SubmissionError(f"path: expected at most {limits.max_total_bytes} bytes of notebooks, got more")
            out.append((rel, _TOO_BIG if st.st_size > limits.max_file_bytes else p.read_bytes()))
    return out


_TOO_BIG = b"\x00too-big"  # stands for a file that was not read because of its size


def _zip_files(path: Path, limits: SizeLimits) -> list[tuple[str, bytes]]:
    out = []
    try:
        with zipfile.ZipFile(path) as zf:
            infos = zf.infolist()
            if len(infos) > limits.max_entries:
                raise SubmissionError(f"path: expected at most {limits.max_entries} entries, got {len(infos)}")
            declared = 0
            for info in infos:
                _check_member_name(info.filename)
                declared += info.file_size
            if declared > limits.max_total_bytes:
                raise SubmissionError(f"path: expected at most {limits.max_total_bytes} bytes unpacked, got {declared}")
            for info in infos:
                name = info.filename.replace("\\", "/")
                is_link = stat.S_ISLNK(info.external_attr >> 16)
                if info.is_dir() or is_link or not _is_candidate(name):
                    continue
                if info.flag_bits & 0x1:
                    out.append((name, b"\x00encrypted"))
                    continue
                if info.file_size > limits.max_file_bytes:
                    out.append((name, _TOO_BIG))
                    continue
                with zf.open(info) as fh:
                    # Read one byte past the limit: the declared size of a member can lie.
                    data = fh.read(limits.max_file_bytes + 1)
                out.append((name, _TOO_BIG if len(data) > limits.max_file_bytes else data))
    except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, EOFError, OSError) as exc:
        raise SubmissionError(f"path: expected a readable zip archive ({exc})") from None
    return out


def _check_member_name(raw: str) -> None:
    name = raw.replace("\\", "/")
    parts = PurePosixPath(name).parts
    if name.startswith("/") or re.match(r"^[A-Za-z]:", name) or ".." in parts or "\x00" in name:
        raise SubmissionError(
            f"path: expected archive entries inside the archive's folder, got {raw!r} "
            "(an absolute path or '..'); the archive was rejected"
        )


_Q_NUMBER = re.compile(r"(?:^|[^a-z0-9])q(\d+)(?!\d)")


def _qkey(stem: str) -> str:
    m = _Q_NUMBER.search(stem.lower())
    return f"q{int(m.group(1))}" if m else stem


def _stem_of(name: str, stems: Sequence[str]) -> str | None:
    base = PurePosixPath(name).name.lower()
    m = _Q_NUMBER.search(base)
    if m is None:
        return None
    key = f"q{int(m.group(1))}"
    return next((s for s in stems if _qkey(s) == key), None)


def _preference(name: str, stem: str) -> tuple:
    p = PurePosixPath(name)
    return (p.stem.lower() != stem, p.suffix.lower() != ".ipynb",
            not p.name.lower().startswith(_qkey(stem)), len(p.parts), len(name), name)


# ------------------------------------------------------------------------------------------------
# notebooks and cells


@dataclass(frozen=True)
class _Cell:
    number: int        # 1-based position among all cells (markdown included), as the student counts
    text: str
    first_line: int = 1  # line of the cell's first line in its file (for .py files split in cells)


def parse_notebook(data: bytes | str, *, stem: str, filename: str) -> ParsedNotebook:
    """Parse the .ipynb ``data``; a notebook that cannot be read gives ``readable=False``."""
    try:
        cells = _notebook_cells(data)
    except _Unreadable as exc:
        return ParsedNotebook(stem, filename, readable=False, error=str(exc), expected=_expected(stem))
    return parse_cells(cells, stem=stem, filename=filename)


def parse_python(data: bytes | str, *, stem: str, filename: str) -> ParsedNotebook:
    """Parse a .py file; ``# %%`` lines (the percent format of Jupytext, VS Code, Spyder) split
    it into cells so that a syntax error loses only its cell."""
    try:
        text = _text(data)
    except _Unreadable as exc:
        return ParsedNotebook(stem, filename, readable=False, error=str(exc), expected=_expected(stem))
    lines = text.splitlines(keepends=True)
    starts = [0] + [i for i, line in enumerate(lines) if i > 0 and re.match(r"#\s?%%", line)]
    cells = []
    for k, (a, b) in enumerate(zip(starts, starts[1:] + [len(lines)]), start=1):
        cells.append(_Cell(k, "".join(lines[a:b]), a + 1))
    return parse_cells(cells, stem=stem, filename=filename)


def parse_cells(cells: Iterable[_Cell | str], *, stem: str, filename: str) -> ParsedNotebook:
    """Parse code cells (strings are numbered 1, 2, ...) into the units of one ParsedNotebook."""
    units: list[SourceUnit] = []
    problems: list[CellProblem] = []
    known = set(dir(builtins))
    counts: dict[str, int] = {}
    definitions: dict[str, str] = {}
    for k, cell in enumerate(cells, start=1):
        if isinstance(cell, str):
            cell = _Cell(k, cell)
        origin = f"{filename}, cell {cell.number}" if not filename.lower().endswith(".py") else filename
        try:
            text, tree = _parse_cell(cell.text)
        except SyntaxError as exc:
            line = exc.lineno + cell.first_line - 1 if exc.lineno else None
            problems.append(CellProblem(cell.number, line, f"syntax error: {exc.msg}"))
            continue
        if tree is None:
            continue
        for node in tree.body:
            if not _keep(node, known):
                continue
            names = _bound_names(node)
            known.update(names)
            for name in names:
                counts[name] = counts.get(name, 0) + 1
                definitions[name] = f"{origin}, line {node.lineno + cell.first_line - 1}" if origin == filename else origin
            units.append(SourceUnit(
                origin=origin,
                line=_first_line(node) + cell.first_line - 1,
                source=_segment(text, node),
                future=_future_features(node),
                defines=tuple(names),
            ))
    redefined = {n: c for n, c in counts.items() if c > 1}
    return ParsedNotebook(stem, filename, True, None, tuple(units), tuple(problems), definitions,
                          redefined, _expected(stem))


def _expected(stem: str) -> tuple[str, ...]:
    return functions_of_notebook(stem) if stem in NOTEBOOKS else ()


class _Unreadable(Exception):
    pass


def _text(data: bytes | str) -> str:
    if isinstance(data, str):
        return data
    if data == _TOO_BIG:
        raise _Unreadable("the file is larger than the size limit")
    if data.startswith(b"\x00encrypted"):
        raise _Unreadable("the file is encrypted in the archive")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise _Unreadable(f"it is not UTF-8 text ({exc.reason} at byte {exc.start})") from None


def _notebook_cells(data: bytes | str) -> list[_Cell]:
    import nbformat  # imported here: only notebooks need it

    text = _text(data)
    try:
        raw = json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise _Unreadable(f"it is not valid JSON ({str(exc)[:120]})") from None
    if not isinstance(raw, dict):
        raise _Unreadable("it is JSON but not a notebook")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # missing cell ids and similar schema nits do not matter here
            nb = nbformat.from_dict(raw)
            nb = nbformat.convert(nb, 4) if nb.get("nbformat", 4) != 4 else nb
            cells = nb.get("cells")
    except Exception:  # noqa: BLE001 - nbformat raises many kinds; fall back to the raw JSON below
        cells = raw.get("cells")
    if not isinstance(cells, list):
        raise _Unreadable("it is JSON but has no list of cells")
    out = []
    for k, cell in enumerate(cells, start=1):
        if not isinstance(cell, dict) or cell.get("cell_type") != "code":
            continue
        source = cell.get("source", "")
        if isinstance(source, list):
            source = "".join(s for s in source if isinstance(s, str))
        if isinstance(source, str):
            out.append(_Cell(k, source))
    return out


# Cell magics whose body is ordinary Python that a notebook would run.
_PYTHON_CELL_MAGICS = {"time", "timeit", "capture", "prun", "debug"}


def _parse_cell(text: str) -> tuple[str, ast.Module | None]:
    """The cell's Python text and its tree; (text, None) for a cell in another language."""
    first = text.lstrip().split("\n", 1)[0]
    if first.startswith("%%"):
        magic = first[2:].split(maxsplit=1)[0] if first[2:].strip() else ""
        if magic not in _PYTHON_CELL_MAGICS:
            return text, None
        # Blank the magic line rather than remove it, so line numbers stay those of the cell.
        before, _, rest = text.partition(first)
        text = before + rest
    try:
        return text, ast.parse(text)
    except SyntaxError:
        pass
    cleaned = _strip_magics(text)
    return cleaned, ast.parse(cleaned)  # a SyntaxError here is the cell's real error


def _strip_magics(text: str) -> str:
    try:
        from IPython.core.inputtransformer2 import TransformerManager
    except ImportError:
        TransformerManager = None
    if TransformerManager is not None:
        try:
            return TransformerManager().transform_cell(text)
        except Exception:  # noqa: BLE001, S110 - fall through to the simple rule
            pass
    # Without IPython: shell escapes, line magics and help requests become `pass` at their indent.
    out = []
    for line in text.split("\n"):
        body = line.lstrip()
        if body.startswith(("%", "!")) or re.match(r"[\w.]+\s*=\s*[%!]", body) or (
                body.rstrip().endswith("?") and not body.startswith("#")):
            out.append(line[: len(line) - len(body)] + "pass")
        else:
            out.append(line)
    return "\n".join(out)


# ------------------------------------------------------------------------------------------------
# which statements to keep

# Calls that read files, draw or save: never run while loading definitions.
_SIDE_EFFECT_CALLS = {
    "load", "loadtxt", "genfromtxt", "fromfile", "imread", "open", "read", "read_csv", "save",
    "savez", "savetxt", "savefig", "show", "figure", "subplots", "plot", "scatter", "imshow",
    "system", "run", "Popen", "seed", "urlopen", "get", "post", "input", "print", "eval", "exec",
    "compile", "__import__", "sleep",
}


def _keep(node: ast.stmt, known: set[str]) -> bool:
    if isinstance(node, (ast.Import, ast.ImportFrom, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
        return True
    if isinstance(node, ast.Assign):
        return all(_is_name_target(t) for t in node.targets) and _is_simple(node.value, known)
    if isinstance(node, ast.AnnAssign):
        return isinstance(node.target, ast.Name) and (node.value is None or _is_simple(node.value, known))
    if isinstance(node, ast.Try):
        # The usual optional-import fallback: try: import cv2 / except ImportError: cv2 = None.
        inner = node.body + node.orelse + node.finalbody + [s for h in node.handlers for s in h.body]
        return all(isinstance(s, ast.Pass) or _keep(s, known | _bound_names(node)) for s in inner)
    return False


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
    if isinstance(e, (ast.BoolOp,)):
        return all(_is_simple(v, known) for v in e.values)
    if isinstance(e, ast.Compare):
        return _is_simple(e.left, known) and all(_is_simple(c, known) for c in e.comparators)
    if isinstance(e, ast.Lambda):
        return all(_is_simple(d, known) for d in e.args.defaults + [d for d in e.args.kw_defaults if d])
    if isinstance(e, ast.Call):
        name = e.func.attr if isinstance(e.func, ast.Attribute) else getattr(e.func, "id", None)
        return (name is not None and name not in _SIDE_EFFECT_CALLS and _is_simple(e.func, known)
                and all(_is_simple(a.value if isinstance(a, ast.Starred) else a, known) for a in e.args)
                and all(_is_simple(k.value, known) for k in e.keywords))
    return False


def _bound_names(node: ast.stmt) -> set[str]:
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
        return set().union(*(_bound_names(s) for s in inner)) if inner else set()
    return set()


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

