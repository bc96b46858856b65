"""Find the source of each homework function in a submission (folder, zip, notebooks, .py files).

Parsing only: nothing is run.  Notebook cells are read as JSON; IPython magics and shell lines
(``%matplotlib``, ``!pip``) become blank lines so the rest of the cell still parses.  A cell that
still does not parse is skipped.  When a function is defined several times, the definition that
the grader would use wins: the last one in the file whose name carries the function's question
number (``q2`` for eightpoint), else the last one anywhere.
"""

from __future__ import annotations

import ast
import json
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from core.files import list_files
from core.manifest import NOTEBOOKS, QUESTIONS

__all__ = ["FunctionSource", "SubmissionCode", "FUNCTIONS", "read_submission", "functions_in_source",
           "stub_sources"]

FUNCTIONS: tuple[str, ...] = tuple(f for q in QUESTIONS for f in q.functions)
_NOTEBOOK_OF = {f: q.notebook for q in QUESTIONS for f in q.functions}
_MAX_FILE_BYTES = 20 * 2**20
_MAGIC = re.compile(r"^\s*[%!]")


@dataclass(frozen=True)
class FunctionSource:
    """One definition of a homework function.

    name: the function's name; source: its text (decorators included, dedented as written);
    origin: where it was found ("q2_eightpoint.ipynb, cell 5"); first_line: the line of the
    ``def`` within that cell or file (1-based), so that line k of ``source`` is line
    ``first_line + k - 1`` there.
    """

    name: str
    source: str
    origin: str
    first_line: int = 1


@dataclass(frozen=True)
class SubmissionCode:
    """The homework functions found in one submission: name -> FunctionSource; notes say what was skipped."""

    name: str
    functions: dict
    notes: tuple[str, ...] = ()


def blank_magics(text: str) -> str:
    return "\n".join("" if _MAGIC.match(line) else line for line in text.split("\n"))


def functions_in_source(text: str, origin: str, wanted=FUNCTIONS) -> list[FunctionSource]:
    """Top-level definitions of the names in ``wanted`` in the Python ``text``, in order.

    Raises SyntaxError when ``text`` does not parse even with its magics blanked.
    """
    text = blank_magics(text)
    tree = ast.parse(text)
    lines = text.split("\n")
    found = []
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name in wanted:
            start = min([node.lineno] + [d.lineno for d in node.decorator_list])
            source = "\n".join(lines[start - 1:node.end_lineno])
            found.append(FunctionSource(node.name, source, origin, start))
    return found


def _cells(data: bytes, filename: str) -> list[tuple[str, str]]:
    """(origin, source) of each code cell of a notebook given as bytes."""
    nb = json.loads(data.decode("utf-8", errors="replace"))
    if not isinstance(nb, dict) or not isinstance(nb.get("cells"), list):
        raise ValueError("not a notebook (no list of cells)")
    out = []
    for k, cell in enumerate(nb["cells"], start=1):
        if not isinstance(cell, dict) or cell.get("cell_type") != "code":
            continue
        src = cell.get("source", "")
        src = "".join(src) if isinstance(src, list) else str(src)
        out.append((f"{filename}, cell {k}", src))
    return out


def _question_key(filename: str) -> str | None:
    m = re.search(r"(?:^|[^a-z0-9])q(\d+)", PurePosixPath(filename).name.lower())
    return f"q{m.group(1)}" if m else None


def _files(path: Path) -> list[tuple[str, bytes]]:
    """(name inside the submission, bytes) of each .ipynb and .py file of a folder or zip."""
    keep = (".ipynb", ".py")
    if path.is_dir():
        out = []
        for p, st in sorted(list_files(path).files):   # without recursion: a deep folder stops nothing
            rel = p.relative_to(path).as_posix()
            if (p.suffix in keep and ".ipynb_checkpoints" not in rel
                    and "__MACOSX" not in rel and st.st_size <= _MAX_FILE_BYTES):
                out.append((rel, p.read_bytes()))
        return out
    if zipfile.is_zipfile(path):
        out = []
        with zipfile.ZipFile(path) as zf:
            for info in sorted(zf.infolist(), key=lambda i: i.filename):
                name = info.filename
                if (info.is_dir() or PurePosixPath(name).suffix not in keep or ".ipynb_checkpoints" in name
                        or "__MACOSX" in name or info.file_size > _MAX_FILE_BYTES):
                    continue
                out.append((name, zf.read(info)))
        return out
    if path.is_file() and path.suffix in keep:
        return [(path.name, path.read_bytes())]
    raise ValueError(f"path: expected a folder, a .zip, a .ipynb or a .py, got {str(path)!r}")


def code_units(path: Path, notes: list[str]):
    """(file name, [(origin, source), ...]) of each file of the submission at ``path``: a
    notebook's code cells, or a .py file whole; a file that cannot be read adds a line to ``notes``."""
    for filename, data in _files(path):
        try:
            units = _cells(data, filename) if filename.endswith(".ipynb") else \
                [(filename, data.decode("utf-8", errors="replace"))]
        except (ValueError, UnicodeError) as exc:
            notes.append(f"{filename} could not be read: {exc}")
            continue
        yield filename, units


def read_submission(path: str | Path, name: str | None = None) -> SubmissionCode:
    """The homework functions of the submission at ``path`` (folder, .zip, .ipynb or .py).

    ``name`` defaults to the folder's or file's name without its suffix.
    """
    path = Path(path)
    if not path.exists():
        raise ValueError(f"path: expected an existing folder or file, got {str(path)!r}")
    name = name or (path.name if path.is_dir() else path.stem)
    notes: list[str] = []
    # function -> (priority, order, FunctionSource); priority 1 when the file is the function's notebook.
    best: dict[str, tuple[int, int, FunctionSource]] = {}
    order = 0
    for filename, units in code_units(path, notes):
        key = _question_key(filename)
        for origin, src in units:
            try:
                found = functions_in_source(src, origin)
            except (SyntaxError, ValueError) as exc:
                notes.append(f"{origin} does not parse: {getattr(exc, 'msg', exc)}")
                continue
            for fs in found:
                order += 1
                priority = int(key is not None and _question_key(_NOTEBOOK_OF[fs.name]) == key)
                if fs.name not in best or (priority, order) >= best[fs.name][:2]:
                    best[fs.name] = (priority, order, fs)
    return SubmissionCode(name, {f: best[f][2] for f in FUNCTIONS if f in best}, tuple(notes))


def stub_sources(notebooks_dir: str | Path) -> list[FunctionSource]:
    """The handout's code: every function and top-level statement of the student notebooks
    ``notebooks_dir/<stem>.ipynb`` (the stubs students start from), as FunctionSources named
    by what they define ("<cell>" for a cell's other statements)."""
    out = []
    for stem in NOTEBOOKS:
        p = Path(notebooks_dir) / f"{stem}.ipynb"
        if not p.is_file():
            continue
        for origin, src in _cells(p.read_bytes(), p.name):
            out.append(FunctionSource("<cell>", blank_magics(src), origin, 1))
    return out
