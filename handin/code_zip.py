"""The code zip a student hands to the autograder, and what their notebooks define.

The code zip is a zip of the homework notebooks (``<stem>.ipynb`` at the top level, one per
manifest notebook found) plus, when asked for explicitly or sitting beside them, small ``.py``
helper modules.  Writing it never runs student code: notebooks are read with nbformat and
their code cells parsed with :mod:`ast`, so a notebook that would hang, crash or delete files
is still checked.  Problems come back as a list of warnings in a :class:`CodeZipReport`, never
as an exception, because a half-finished homework must still be submittable.

The same inspection (:func:`inspect_notebook`) tells the PDF cover which questions look
answered and what the student's name is.
"""

from __future__ import annotations

import ast
import difflib
import re
import zipfile
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import nbformat

from core.manifest import NOTEBOOKS, QUESTIONS, functions_of_notebook
from core.notebook import Cell, definitions, notebook_stem, parse_cells

__all__ = [
    "NotebookInfo",
    "Selection",
    "CodeZipReport",
    "select_notebooks",
    "inspect_notebook",
    "student_name",
    "build_code_zip",
]

# A helper module beside the notebooks is welcome, a data file or a stray video is not.
HELPER_SUFFIXES = (".py",)
MAX_HELPER_KB = 256
_HOMEWORK = frozenset(f for q in QUESTIONS for f in q.functions)
NAME_PLACEHOLDERS = {"", "your name", "your name here", "firstname lastname", "first last"}


@dataclass
class Selection:
    """Notebooks picked from what the student pointed at.

    notebooks: paths in manifest order, then any extra notebook given explicitly;
    extras: other small files given explicitly or found beside them (helper modules);
    skipped: (path, reason) for everything left out on purpose.
    """

    notebooks: list[Path]
    extras: list[Path] = field(default_factory=list)
    skipped: list[tuple[Path, str]] = field(default_factory=list)


@dataclass
class NotebookInfo:
    """What one notebook contains, found without running it.

    path: the file; stem: its manifest stem, or None for a notebook the manifest does not know;
    nb: the parsed notebook (nbformat v4) or None when it could not be read;
    implemented: names defined at the top level of a code cell by something other than a stub;
    stubs: functions whose body is still ``pass``/``...``/``raise NotImplementedError``;
    problems: human-readable reasons some cells could not be checked (syntax errors, bad JSON);
    student_name: the value of a ``STUDENT_NAME = "..."`` assignment, if any.
    """

    path: Path
    stem: str | None
    nb: nbformat.NotebookNode | None
    implemented: set[str] = field(default_factory=set)
    stubs: set[str] = field(default_factory=set)
    problems: list[str] = field(default_factory=list)
    student_name: str | None = None

    def missing(self) -> list[str]:
        """Manifest functions of this notebook that are not implemented, in manifest order."""
        if self.stem is None:
            return []
        return [f for f in functions_of_notebook(self.stem) if f not in self.implemented]


@dataclass
class CodeZipReport:
    """The result of :func:`build_code_zip`.

    zip_path: the zip written, or None when nothing could be bundled; included: archive names;
    size_bytes: size of the zip; max_bytes: the cap; missing_notebooks: manifest stems not found;
    missing_functions / stub_functions: per notebook stem, names not defined / still stubs;
    skipped: (path, reason) for files left out; problems: cells or files that could not be read.
    """

    zip_path: Path | None
    included: list[str]
    size_bytes: int
    max_bytes: int
    missing_notebooks: list[str]
    missing_functions: dict[str, list[str]]
    stub_functions: dict[str, list[str]]
    skipped: list[tuple[Path, str]]
    problems: list[str]

    @property
    def too_large(self) -> bool:
        return self.size_bytes > self.max_bytes

    @property
    def warnings(self) -> list[str]:
        """One sentence per problem, most serious first (empty when everything is in)."""
        out = []
        if self.too_large:
            out.append(f"the zip is {self.size_bytes / 2**20:.1f} MB, over the {self.max_bytes / 2**20:.0f} MB "
                       "limit: clear the outputs of cells with large figures and save again")
        out += [f"notebook {stem}.ipynb not found" for stem in self.missing_notebooks]
        for stem, names in self.stub_functions.items():
            out.append(f"{stem}.ipynb: still a stub (raises NotImplementedError): {', '.join(names)}")
        for stem, names in self.missing_functions.items():
            out.append(f"{stem}.ipynb: not defined: {', '.join(names)}")
        out += self.problems
        out += [f"left out {p.name}: {why}" for p, why in self.skipped]
        return out

    @property
    def ok(self) -> bool:
        """True when every notebook and function is there and the zip fits the cap."""
        return not (self.too_large or self.missing_notebooks or self.missing_functions
                    or self.stub_functions or self.problems)

    def __str__(self) -> str:
        head = (f"{self.zip_path}: {len(self.included)} file(s), {self.size_bytes / 2**20:.2f} MB"
                if self.zip_path else "no zip written")
        lines = [head] + [f"  {name}" for name in self.included]
        lines += ["warning: " + w for w in self.warnings] or ["all expected functions are defined"]
        return "\n".join(lines)


def _paths(source, argname: str) -> tuple[list[Path], bool]:
    """(paths, came_from_folder) for a folder, one file, or an iterable of files."""
    if isinstance(source, (str, Path)):
        p = Path(source)
        if p.is_dir():
            return sorted(q for q in p.iterdir() if q.is_file()), True
        items = [p]
    else:
        try:
            items = [Path(s) for s in source]
        except TypeError:
            raise ValueError(f"{argname}: expected a folder or a list of files, "
                             f"got {type(source).__name__}") from None
    if not items:
        raise ValueError(f"{argname}: expected at least one notebook, got an empty list")
    for p in items:
        if not p.is_file():
            raise ValueError(f"{argname}: expected a folder or existing files, {str(p)!r} does not exist")
    return items, False


def _near_miss(stem: str) -> str | None:
    """The manifest stem a misnamed copy ("q2_eightpoint (1)", "q2_eightpoint-Copy1") stands for."""
    for known in NOTEBOOKS:
        if stem.startswith(known):
            return known
    close = difflib.get_close_matches(stem, NOTEBOOKS, n=1, cutoff=0.8)
    return close[0] if close else None


def select_notebooks(source, *, argname: str = "notebooks", allow_helpers: bool = False) -> Selection:
    """Pick the homework notebooks from a folder or from a list of files.

    Parameters
    ----------
    source : str or Path or iterable of str/Path
        A folder (its top-level ``<stem>.ipynb`` files whose stem is in the manifest are taken,
        other notebooks are skipped with a reason), one notebook, or a list of files (every
        notebook listed is taken; manifest ones first, in manifest order).
    argname : str
        The caller's argument name, used in error messages.
    allow_helpers : bool
        Also take small ``.py`` files (helper modules) found or listed; larger ones and files of
        any other type are skipped with a reason.

    Raises
    ------
    ValueError
        When a listed file does not exist, two notebooks share a stem, or no notebook is found.
    """
    paths, from_folder = _paths(source, argname)
    by_stem: dict[str, Path] = {}
    renamed: dict[str, list[Path]] = {}
    others: list[Path] = []
    sel = Selection(notebooks=[])
    for p in paths:
        if p.suffix == ".ipynb":
            stem = stem_of(p)
            if p.stem in NOTEBOOKS:
                if p.stem in by_stem:
                    raise ValueError(f"{argname}: expected one notebook per stem, got {by_stem[p.stem]} and {p}")
                by_stem[p.stem] = p
            elif stem is not None:  # renamed by Colab or a browser; its metadata says which it is
                renamed.setdefault(stem, []).append(p)
            elif from_folder:
                hint = _near_miss(p.stem)
                why = (f"not a homework notebook name; rename it {hint}.ipynb if it is your answer"
                       if hint else "not one of the homework notebooks (pass it explicitly to include it)")
                sel.skipped.append((p, why))
            else:
                others.append(p)
        elif p.suffix in HELPER_SUFFIXES and allow_helpers:
            kb = p.stat().st_size / 1024
            if kb > MAX_HELPER_KB:
                sel.skipped.append((p, f"{kb:.0f} KB, larger than the {MAX_HELPER_KB} KB allowed for a helper module"))
            else:
                sel.extras.append(p)
        elif not from_folder:
            # A data file sitting in the folder is not worth a word; one the student named is.
            size = p.stat().st_size / 2**20
            sel.skipped.append((p, f"not a notebook or helper module ({size:.1f} MB)"))
    for stem, copies in renamed.items():
        # The exact name wins; else the most recently saved copy.
        copies.sort(key=lambda q: (q.stat().st_mtime, q.name), reverse=True)
        if stem not in by_stem:
            by_stem[stem] = copies.pop(0)
        sel.skipped += [(q, f"another notebook for {stem}, {by_stem[stem].name}, is used") for q in copies]
    sel.notebooks = [by_stem[s] for s in NOTEBOOKS if s in by_stem] + others
    if not sel.notebooks:
        found = ", ".join(p.name for p in paths[:8]) or "nothing"
        raise ValueError(f"{argname}: expected homework notebooks ({', '.join(s + '.ipynb' for s in NOTEBOOKS)}), "
                         f"found {found}")
    return sel


def stem_of(path: Path) -> str | None:
    """The homework stem of a notebook file: its name when that is ``<stem>.ipynb``, else the stem
    in its metadata (a copy named "Copy of q2_eightpoint.ipynb" by Colab), else None."""
    path = Path(path)
    if path.stem in NOTEBOOKS:
        return path.stem
    try:
        stem = notebook_stem(path.read_bytes())
    except OSError:
        return None
    return stem if stem in NOTEBOOKS else None


def _is_stub(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """A body that is only a docstring, pass, ``...`` or contains a top-level NotImplementedError raise."""
    body = list(fn.body)
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
            and isinstance(body[0].value.value, str):
        body = body[1:]
    for stmt in body:
        if isinstance(stmt, ast.Raise) and stmt.exc is not None:
            exc = stmt.exc.func if isinstance(stmt.exc, ast.Call) else stmt.exc
            if isinstance(exc, ast.Name) and exc.id == "NotImplementedError":
                # Code before the raise is the skeleton's setup, not an answer.
                return True
    return all(isinstance(s, ast.Pass) or (isinstance(s, ast.Expr) and isinstance(s.value, ast.Constant)
                                           and s.value.value is Ellipsis) for s in body)


def _scan(defs, info: NotebookInfo) -> None:
    for d in defs:
        node = d.node
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            # A later definition replaces an earlier one, as it would when the cells run.
            if _is_stub(node):
                info.stubs.add(node.name)
                info.implemented.discard(node.name)
            else:
                info.implemented.add(node.name)
                info.stubs.discard(node.name)
            continue
        value = getattr(node, "value", None)
        if "STUDENT_NAME" in d.defines and isinstance(value, ast.Constant) and isinstance(value.value, str):
            if value.value.strip().lower() not in NAME_PLACEHOLDERS:
                info.student_name = value.value.strip()
            continue
        for n in d.defines:  # imports, classes, ``triangulate = my_triangulate``, try-import blocks
            info.implemented.add(n)
            info.stubs.discard(n)


def inspect_notebook(path) -> NotebookInfo:
    """Read a notebook and find, without running it, what its code cells define.

    Parameters
    ----------
    path : str or Path
        An ``.ipynb`` file.

    Returns
    -------
    NotebookInfo
        ``nb`` is None and ``problems`` says why when the file is not a readable notebook.
    """
    path = Path(path)
    info = NotebookInfo(path=path, stem=stem_of(path), nb=None)
    try:
        info.nb = nbformat.read(path, as_version=4)
    except Exception as exc:  # bad JSON, unknown nbformat, not a notebook at all
        info.problems.append(f"{path.name}: not a readable notebook ({type(exc).__name__}: {exc})")
        return info
    parsed, problems = parse_cells(Cell(k, c.source) for k, c in enumerate(info.nb.cells, start=1)
                                   if c.cell_type == "code")
    info.problems += [f"{path.name}: code cell {p.cell} has a syntax error (line {p.line}: "
                      f"{p.message.removeprefix('syntax error: ')}); its definitions were not checked"
                      for p in problems]
    _scan(definitions(parsed, constants=True, links=True, homework=_HOMEWORK), info)
    return info


def student_name(infos: Iterable[NotebookInfo]) -> str | None:
    """The first non-placeholder ``STUDENT_NAME`` found, in the order given."""
    return next((i.student_name for i in infos if i.student_name), None)


def _safe_arcname(name: str) -> str:
    # Archive names stay flat and portable whatever the student called the file.
    return re.sub(r"[^A-Za-z0-9._ ()-]", "_", name)


def build_code_zip(folder_or_notebooks, out_zip, *, max_mb: float = 50.0) -> CodeZipReport:
    """Zip the student's notebooks for the autograder and check what they define.

    Parameters
    ----------
    folder_or_notebooks : str or Path or iterable of str/Path
        A folder holding the homework notebooks (``q2_eightpoint.ipynb`` ...), or a list of files.
        Small ``.py`` helper modules found or listed are included; anything else is left out
        with a reason in ``report.skipped``.
    out_zip : str or Path
        The zip to write (its folder is created). Notebooks go in at the top level.
    max_mb : float
        Size cap of the zip in MiB; a larger zip is still written but ``report.ok`` is False.

    Returns
    -------
    CodeZipReport
        ``report.warnings`` lists what is missing: notebooks, functions not defined or still
        stubs, cells with syntax errors, files left out, an oversize zip. Nothing raises for those.

    Raises
    ------
    ValueError
        When ``folder_or_notebooks`` names no notebook at all, a listed file does not exist, or
        ``max_mb`` is not a positive number.
    """
    try:
        max_mb = float(max_mb)
    except (TypeError, ValueError):
        raise ValueError(f"max_mb: expected a positive number, got {max_mb!r}") from None
    if not max_mb > 0:
        raise ValueError(f"max_mb: expected a positive number, got {max_mb!r}")
    sel = select_notebooks(folder_or_notebooks, argname="folder_or_notebooks", allow_helpers=True)
    infos = [inspect_notebook(p) for p in sel.notebooks]
    present = {i.stem for i in infos if i.stem}
    missing_functions: dict[str, list[str]] = {}
    stubs: dict[str, list[str]] = {}
    for info in infos:
        # A stub is reported once, as a stub, not also as "not defined".
        if names := [f for f in info.missing() if f in info.stubs]:
            stubs[info.stem] = names
        if names := [f for f in info.missing() if f not in info.stubs]:
            missing_functions[info.stem] = names

    out_zip = Path(out_zip)
    out_zip.parent.mkdir(parents=True, exist_ok=True)
    included: list[str] = []
    with zipfile.ZipFile(out_zip, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for p in sel.notebooks + sel.extras:
            # A renamed homework notebook goes in under its own name.
            stem = stem_of(p) if p.suffix == ".ipynb" else None
            arcname = f"{stem}.ipynb" if stem else _safe_arcname(p.name)
            if arcname in included:
                sel.skipped.append((p, f"another file is already called {arcname} in the zip"))
                continue
            zf.write(p, arcname)
            included.append(arcname)
    return CodeZipReport(
        zip_path=out_zip,
        included=included,
        size_bytes=out_zip.stat().st_size,
        max_bytes=int(max_mb * 2**20),
        missing_notebooks=[s for s in NOTEBOOKS if s not in present],
        missing_functions=missing_functions,
        stub_functions=stubs,
        skipped=sel.skipped,
        problems=[msg for i in infos for msg in i.problems],
    )


def add_arguments(p) -> None:
    """The arguments of ``python -m handin zip [NOTEBOOK_DIR or files...] --out hw4_code.zip``."""
    p.add_argument("notebooks", nargs="*", type=Path,
                   help="a folder of notebooks or notebook files (default: ./notebooks if present, else .)")
    p.add_argument("--out", type=Path, default=Path("hw4_code.zip"), help="zip to write (default hw4_code.zip)")
    p.add_argument("--max-mb", type=float, default=50.0, help="size cap of the zip in MB (default 50)")


def main(args) -> int:
    """Run ``python -m handin zip``: 0 everything in, 1 something missing or the zip too large."""
    local = Path("notebooks")
    source = args.notebooks or (local if local.is_dir() and any(local.glob("q*.ipynb")) else Path("."))
    if isinstance(source, list) and len(source) == 1:
        source = source[0]
    report = build_code_zip(source, args.out, max_mb=args.max_mb)
    print(report)
    return 0 if report.ok else 1
