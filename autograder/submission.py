"""Read a student's submission and find the code of each notebook, by parsing only (never running it).

A submission is a folder or a .zip of the per-question notebooks (``q2_eightpoint.ipynb`` ...), or
of ``.py`` files.  Files are matched to the manifest's notebooks by the question number in their
name (``q2``, ``Q2 eightpoint (1).ipynb``, ``hw4_q2.py``), wherever they sit in the tree, and a
notebook whose name has no question number by the stem the kit wrote in its metadata.

From each notebook we keep what defines things (:func:`core.notebook.definitions`, the kit's one
rule set): top-level imports, function and class definitions, ``try`` blocks made only of those,
and assignments of simple constants, but not statements that run the homework (the notebooks'
self-checks, ``try_run``, ``from_notebook``: the grader loads every notebook itself).  Each kept
statement becomes a ``SourceUnit`` that the sandbox executes on its own, so one failing import
does not lose the definitions after it; since units run in order, the last definition of a name
wins.  :meth:`Submission.units` is exactly the code the grading job loads; :meth:`Submission.notes`
says, as data, what the student should know (unreadable files, syntax errors, redefinitions,
missing or borrowed functions, files not used).  A code cell with a syntax error is skipped whole;
a notebook that is not valid JSON is unreadable and the others are still used.
"""

from __future__ import annotations

import os
import re
import stat
import zipfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

from core.manifest import NOTEBOOKS, QUESTIONS, functions_of_notebook
from core.notebook import (
    Cell,
    CellProblem,
    NotebookUnreadable,
    code_cells,
    definitions,
    notebook_stem,
    parse_cells as parse_code_cells,
)

__all__ = [
    "CellProblem",
    "Note",
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

_HOMEWORK = frozenset(f for q in QUESTIONS for f in q.functions)


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
class Note:
    """Something about the submission the student should know, as data.

    kind: "unreadable" (``detail``: why), "syntax_error" (``cell``, ``line``, ``detail``: the
    message), "redefined" (``name``, ``count``, ``detail``: the winning definition), "missing"
    (``name``), "borrowed" (``name`` found in another notebook, ``detail``: where), "no_file"
    (``stem`` has no file), "not_used" (``file`` left out, ``detail``: why).
    file: the submission's file concerned (None for "no_file" and "borrowed").
    """

    kind: str
    file: str | None = None
    stem: str | None = None
    name: str | None = None
    cell: int | None = None
    line: int | None = None
    count: int | None = None
    detail: str = ""

    def __str__(self) -> str:
        if self.kind == "unreadable":
            return f"{self.file} could not be read: {self.detail}. None of its code was used."
        if self.kind == "syntax_error":
            where = f" (line {self.line})" if self.line else ""
            return f"{self.file}, cell {self.cell}: {self.detail}{where}; the code of that cell was not used."
        if self.kind == "redefined":
            return f"{self.file}: {self.name} is defined {self.count} times; the last one ({self.detail}) is used."
        if self.kind == "missing":
            return f"{self.file}: {self.name} is not defined."
        if self.kind == "borrowed":
            return f"{self.name} was found in {self.detail} and is used from there."
        if self.kind == "no_file":
            return f"No file for {self.stem} (expected a notebook whose name starts with {_qkey(self.stem)})."
        if self.kind == "not_used":
            return f"Not used: {self.file} ({self.detail})"
        return f"{self.file}: {self.detail}"


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

    def notes(self) -> list[Note]:
        """What the student should know about this file: unreadable, syntax errors, redefinitions, missing."""
        f = self.filename
        if not self.readable:
            return [Note("unreadable", f, self.stem, detail=self.error or "")]
        notes = [Note("syntax_error", f, self.stem, cell=p.cell, line=p.line, detail=p.message)
                 for p in self.syntax_errors]
        notes += [Note("redefined", f, self.stem, name=name, count=self.redefined[name],
                       detail=self.definitions[name]) for name in self.expected if name in self.redefined]
        notes += [Note("missing", f, self.stem, name=name) for name in self.missing]
        return notes


@dataclass(frozen=True)
class Submission:
    """A parsed submission: one ParsedNotebook per manifest stem found.

    notebooks: stem -> ParsedNotebook; missing_notebooks: stems with no file; ignored: files not
    used, as "not_used" notes (``file`` and the reason in ``detail``).
    """

    name: str
    notebooks: dict[str, ParsedNotebook]
    missing_notebooks: tuple[str, ...] = ()
    ignored: tuple[Note, ...] = ()

    def units(self) -> tuple[SourceUnit, ...]:
        """The student's code the grading job loads, in order.

        Every kept statement of every notebook in manifest order, then again each notebook's own
        definitions of its own functions: a function is taken from its own notebook when it is
        defined there, and borrowed from another notebook otherwise.
        """
        found = [s for s in NOTEBOOKS if s in self.notebooks]
        units = [u for s in found for u in self.notebooks[s].units]
        for s in found:
            own = set(functions_of_notebook(s))
            units += [u for u in self.notebooks[s].units if own & set(u.defines)]
        return tuple(units)

    def where_defined(self, function: str, stem: str) -> str | None:
        """Origin of the definition of ``function`` that :meth:`units` makes win for notebook ``stem``, or None."""
        if stem in self.notebooks and function in self.notebooks[stem].definitions:
            return self.notebooks[stem].definitions[function]
        found = None
        for s in NOTEBOOKS:
            if s != stem and s in self.notebooks and function in self.notebooks[s].definitions:
                found = self.notebooks[s].definitions[function]
        return found

    def notes(self) -> list[Note]:
        """Every note about the submission, in manifest order, then the files not used."""
        notes = []
        for stem in NOTEBOOKS:
            if stem in self.missing_notebooks:
                notes.append(Note("no_file", stem=stem))
            elif stem in self.notebooks:
                nb = self.notebooks[stem]
                notes.extend(nb.notes())
                for f in nb.missing:
                    elsewhere = self.where_defined(f, stem)
                    if elsewhere:
                        notes.append(Note("borrowed", stem=stem, name=f, detail=elsewhere))
        return notes + list(self.ignored)


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
    ignored: list[Note] = []
    for name, data in files:
        stem = _stem_of(name, stems)
        if stem is None and name.lower().endswith(".ipynb"):
            meta = notebook_stem(data)  # a renamed notebook still knows which one it is
            stem = meta if meta in stems else None
        if stem is None:
            ignored.append(Note("not_used", name, detail="its name does not start with a question number"))
        else:
            by_stem.setdefault(stem, []).append((name, data))

    notebooks: dict[str, ParsedNotebook] = {}
    for stem, candidates in by_stem.items():
        candidates.sort(key=lambda nd: _preference(nd[0], stem))
        name, data = candidates[0]
        ignored.extend(Note("not_used", other, stem, detail=f"another file, {name}, was used for {stem}")
                       for other, _ in candidates[1:])
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


def parse_notebook(data: bytes | str, *, stem: str, filename: str) -> ParsedNotebook:
    """Parse the .ipynb ``data``; a notebook that cannot be read gives ``readable=False``."""
    return _parse(data, stem=stem, filename=filename, python_file=False)


def parse_python(data: bytes | str, *, stem: str, filename: str) -> ParsedNotebook:
    """Parse a .py file; ``# %%`` lines (the percent format of Jupytext, VS Code, Spyder) split
    it into cells so that a syntax error loses only its cell."""
    return _parse(data, stem=stem, filename=filename, python_file=True)


def _parse(data: bytes | str, *, stem: str, filename: str, python_file: bool) -> ParsedNotebook:
    try:
        if data == _TOO_BIG:
            raise NotebookUnreadable("the file is larger than the size limit")
        if isinstance(data, bytes) and data.startswith(b"\x00encrypted"):
            raise NotebookUnreadable("the file is encrypted in the archive")
        cells = code_cells(data, python_file=python_file)
    except NotebookUnreadable as exc:
        return ParsedNotebook(stem, filename, readable=False, error=str(exc), expected=_expected(stem))
    return parse_cells(cells, stem=stem, filename=filename)


def parse_cells(cells: Iterable[Cell | str], *, stem: str, filename: str) -> ParsedNotebook:
    """Parse code cells (strings are numbered 1, 2, ...) into the units of one ParsedNotebook."""
    parsed, problems = parse_code_cells(cells)
    units: list[SourceUnit] = []
    counts: dict[str, int] = {}
    found: dict[str, str] = {}
    python_file = filename.lower().endswith(".py")
    for d in definitions(parsed, constants=True, links=False, homework=_HOMEWORK):
        origin = filename if python_file else f"{filename}, cell {d.cell.number}"
        for name in d.defines:
            counts[name] = counts.get(name, 0) + 1
            found[name] = f"{origin}, line {d.lineno}" if python_file else origin
        units.append(SourceUnit(origin=origin, line=d.line, source=d.source, future=d.future, defines=d.defines))
    redefined = {n: c for n, c in counts.items() if c > 1}
    return ParsedNotebook(stem, filename, True, None, tuple(units), tuple(problems), found,
                          redefined, _expected(stem))


def _expected(stem: str) -> tuple[str, ...]:
    return functions_of_notebook(stem) if stem in NOTEBOOKS else ()
