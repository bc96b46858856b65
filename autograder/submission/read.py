"""Read a student's submission and find the code of each homework function, by parsing only (never running it).

A submission is whatever the student handed in, as a folder or a .zip (nested folders and odd
names included): the kit's per-question notebooks (``q2_eightpoint.ipynb`` ...), one notebook
holding everything, the course's ``submission.py`` with ``helper.py``, ``findM2.py`` and
``visualize.py`` (2018-2021), one ``.py`` file per part (``q2_1_eightpoint.py``,
``q3_1_essential_matrix.py`` ... 2022-2024), or any mix.  Every ``.ipynb`` and ``.py`` file is
read; a file answers a notebook of the manifest when its name holds the question number (``q2``,
``Q2 eightpoint (1).ipynb``, ``hw4_q2.py``) or its metadata holds the stem the kit wrote.

From each file we keep what defines things (:func:`core.notebook.definitions`, the kit's one
rule set): top-level imports, function and class definitions, ``try`` blocks made only of those,
and assignments of simple constants, but not statements that run the homework (self-checks,
plots, data loading, ``if __name__ == "__main__":`` blocks).  Each kept statement becomes a
``SourceUnit`` that the sandbox executes on its own, so one failing import does not lose the
definitions after it.

How the files fit together (:mod:`autograder.submission.layout` holds the rules):

- notebooks run in one namespace, the one the grader calls into (as the kit's notebooks share
  their functions);
- each ``.py`` file is a module of its own name inside the sandbox (``submission``,
  ``q3_1_essential_matrix``, and ``code.submission`` for ``code/submission.py``), its kept
  statements its body, so the student's ``from q3_1_essential_matrix import essentialMatrix`` works
  as on their machine; a module is served from the submitted source, never from disk;
- ``helper`` (the course's helper file) and ``helpers`` are the kit's given helpers
  (``starter``: refineF, camera2, ransacF, rodrigues ...) unless the student ships their own;
- every homework function found is put in the grader's namespace; when it is defined in several
  files, the file whose name or notebook matches its question is used, else the last one in
  reading order, and a note says which and why (:func:`autograder.submission.layout.choose`);
- a module that uses a name it never defines (a file exported from the kit's notebooks, which
  shared one namespace) finds it in the grader's namespace.

:meth:`Submission.units` is exactly the code the grading job loads; :meth:`Submission.notes`
says, as data, what the student should know (unreadable files, syntax errors, redefinitions,
duplicates and the one used, missing or borrowed functions, helpers given by the kit).
:attr:`Submission.functions` records, for each homework function found, where it is and its
parameters as written, so the grader can recognise another course year's signature.  A code cell
with a syntax error is skipped whole; a notebook that is not valid JSON is unreadable and the
other files are still used.
"""

from __future__ import annotations

import ast
import re
import stat
import zipfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path, PurePosixPath

from core.files import list_files
from core.manifest import GIVEN_HELPERS, NOTEBOOKS, QUESTIONS, functions_of_notebook

from .layout import (
    GIVEN_HELPER_MODULES,
    GIVEN_HELPER_SOURCE,
    Candidate,
    Signature,
    another_years_ransacF,
    choose,
    free_globals,
    module_names,
    private_module_name,
    signature_of,
)
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
    "FoundFunction",
    "Note",
    "ParsedNotebook",
    "SizeLimits",
    "SourceUnit",
    "Submission",
    "SubmissionError",
    "load_submission",
    "own_helper_note",
    "parse_notebook_cells",
    "parse_notebook",
    "parse_python",
]

_HOMEWORK = frozenset(f for q in QUESTIONS for f in q.functions)
_QUESTION_OF = {f: q for q in QUESTIONS for f in q.functions}
GIVEN_HELPERS_ORIGIN = "the kit's given helpers (starter)"


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
    imports; defines: the names it binds; module: None for code run in the grader's namespace,
    else the name of the student's module whose body it is part of (the child serves that
    module to ``import`` statements from these units, never from disk).
    """

    origin: str
    line: int
    source: str
    future: tuple[str, ...] = ()
    defines: tuple[str, ...] = ()
    module: str | None = None

    def to_job(self) -> dict:
        """The unit as the child reads it."""
        job = {"origin": self.origin, "line": self.line, "source": self.source, "future": list(self.future)}
        if self.module is not None:
            job["module"] = self.module
        return job


@dataclass(frozen=True)
class Note:
    """Something about the submission the student should know, as data.

    kind: "unreadable" (``detail``: why), "syntax_error" (``cell``, ``line``, ``detail``: the
    message), "redefined" (``name``, ``count``, ``detail``: the winning definition), "missing"
    (``name``; ``file`` None when no file answers its notebook), "borrowed" (``name`` found in
    another file, ``detail``: where), "no_file" (``stem`` has no file and none of its functions
    was found), "not_used" (``file`` left out, ``detail``: why), "duplicate" (``name`` defined in
    ``count`` files; ``file`` the one used, ``detail``: why and where the others are),
    "given_helper" (``name``: the module, ``file``: a file importing it; the kit's helpers are
    given), "module_name" (``name`` claimed by several files; ``file`` the one importable by it),
    "other_year" (``name``: a helper the kit gives, defined by the student with an earlier year's
    signature, ``detail``; ``file``: where), "own_helper" (``name``: a helper the kit gives
    (``core.manifest.GIVEN_HELPERS``) that the student defines, ``detail``: where; it is what runs).
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
            if self.file is None:
                return f"{self.name} is not defined in any file of the submission."
            return f"{self.file}: {self.name} is not defined."
        if self.kind == "borrowed":
            return f"{self.name} was found in {self.detail} and is used from there."
        if self.kind == "no_file":
            return (f"No file for {self.stem} (expected a notebook whose name starts with {_qkey(self.stem)}, "
                    "or its functions in any file).")
        if self.kind == "not_used":
            return f"Not used: {self.file} ({self.detail})"
        if self.kind == "duplicate":
            return f"{self.name} is defined in {self.count} files; the one in {self.file} is used: {self.detail}."
        if self.kind == "given_helper":
            return (f"{self.file} imports {self.name}, which the submission does not contain: the kit's given "
                    "helpers (refineF, camera2, ransacF, rodrigues ...) were used for it.")
        if self.kind == "other_year":
            return (f"{self.file}: your own {self.name}{self.detail} was recognised as another course year's "
                    f"signature (no eightpoint argument). This homework gives {self.name} (starter) and does not "
                    "grade it; the grader never calls yours.")
        if self.kind == "own_helper":
            return own_helper_note(self.name, self.detail)
        if self.kind == "module_name":
            return f"Several files are named {self.name}; import {self.name} gives {self.file} ({self.detail})."
        return f"{self.file}: {self.detail}"


@dataclass(frozen=True)
class ParsedNotebook:
    """What was found in one file of the submission.

    stem: the manifest's notebook stem it answers ("q2_eightpoint"), "" when none; filename: its
    path inside the submission; readable: False when the file could not be read at all
    (``error`` says why); units: the kept statements in file order; syntax_errors: skipped
    cells; definitions: each bound name (imports included) -> origin of its last (winning)
    definition; redefined: names bound more than once -> how many times; expected: the functions
    the manifest lists for this notebook; functions: each name the file itself defines as a
    function (``def`` or ``name = lambda``, not an import) -> origin of its last definition;
    signatures: the same names -> parameters of that definition; free: names the kept code reads
    but never binds at top level.
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
    functions: dict[str, str] = field(default_factory=dict)
    signatures: dict[str, Signature] = field(default_factory=dict)
    free: frozenset[str] = frozenset()

    @property
    def missing(self) -> tuple[str, ...]:
        """Expected functions this notebook does not define."""
        return tuple(f for f in self.expected if f not in self.definitions)

    @property
    def is_python(self) -> bool:
        """True for a .py file (a module of its own in the sandbox), False for a notebook."""
        return self.filename.lower().endswith(".py")

    @property
    def source(self) -> str:
        """All kept statements as one program (for reading; the sandbox runs ``units``)."""
        return "\n\n".join(f"# {u.origin}, line {u.line}\n{u.source}" for u in self.units) + "\n"

    def notes(self) -> list[Note]:
        """What the student should know about this file: unreadable, syntax errors, redefinitions, missing."""
        f = self.filename
        if not self.readable:
            return [Note("unreadable", f, self.stem or None, detail=self.error or "")]
        notes = [Note("syntax_error", f, self.stem or None, cell=p.cell, line=p.line, detail=p.message)
                 for p in self.syntax_errors]
        notes += [Note("redefined", f, self.stem or None, name=name, count=self.redefined[name],
                       detail=self.definitions[name])
                  for name in sorted(self.redefined, key=_homework_order) if name in _HOMEWORK]
        notes += [Note("missing", f, self.stem or None, name=name) for name in self.missing]
        return notes


@dataclass(frozen=True)
class FoundFunction:
    """A homework function found in the submission, as the grader uses it.

    name: "findM2"; question: its question id ("Q3.3"); filename: the file it is taken from;
    origin: where in that file ("submission.py, line 80", "q3.ipynb, cell 5"); module: the
    student's module it lives in (None for a notebook); signature: its parameters as written
    (another year's ``findM2(F, pts1, pts2, intrinsics, filename)`` is recognisable); reason:
    why this definition is used; others: origins of the definitions in other files, not used.
    """

    name: str
    question: str
    filename: str
    origin: str
    module: str | None
    signature: Signature | None
    reason: str = "the only definition"
    others: tuple[str, ...] = ()

    @property
    def params(self) -> tuple[str, ...]:
        """The parameter names, in order (positional, then keyword-only)."""
        if self.signature is None:
            return ()
        return self.signature.positional + self.signature.kwonly


@dataclass(frozen=True)
class Submission:
    """A parsed submission.

    notebooks: stem -> the file answering that notebook of the manifest (by its name or
    metadata; else, for a hand-in such as ``submission.py``, the file its functions come from);
    missing_notebooks: stems with no file and none of their functions found; ignored: files not
    used, as "not_used" notes; files: every file read, by its path in the submission, in reading
    order; modules: the student's module names -> the file each one is (``helper`` ->
    :data:`GIVEN_HELPERS_ORIGIN` when the kit gives it); functions: every homework function found
    -> :class:`FoundFunction`; layout_notes: notes about how the files fit together.
    """

    name: str
    notebooks: dict[str, ParsedNotebook]
    missing_notebooks: tuple[str, ...] = ()
    ignored: tuple[Note, ...] = ()
    files: dict[str, ParsedNotebook] = field(default_factory=dict)
    modules: dict[str, str] = field(default_factory=dict)
    functions: dict[str, FoundFunction] = field(default_factory=dict)
    layout_notes: tuple[Note, ...] = ()
    job: tuple[SourceUnit, ...] = ()

    def units(self) -> tuple[SourceUnit, ...]:
        """The student's code the grading job loads, in order.

        First the bodies of the student's modules (units with ``module`` set; the child serves
        them to ``import`` statements), then every kept statement of every notebook (manifest
        order, then the others in path order), then an import of each module (so its code runs
        and its errors are reported), then each homework function bound from the definition
        :attr:`functions` chose (a notebook's definition run again, a module's imported), and
        last, for modules relying on a name they never define, that name from the grader's
        namespace.
        """
        return self.job

    def where_defined(self, function: str, stem: str | None = None) -> str | None:
        """Origin of the definition of ``function`` that :meth:`units` makes win, or None.
        (``stem`` is accepted for compatibility; the choice is the same for every notebook.)"""
        found = self.functions.get(function)
        return found.origin if found else None

    def signature(self, function: str) -> Signature | None:
        """The parameters of the homework function ``function`` as the student wrote them, or None."""
        found = self.functions.get(function)
        return found.signature if found else None

    def notes(self) -> list[Note]:
        """Every note about the submission: per file (reading order), then per notebook of the
        manifest (missing, borrowed, no file), then how the files fit together, then files not used."""
        notes = []
        for pf in self.files.values():
            notes += [n for n in pf.notes() if n.kind != "missing"]
        for stem in NOTEBOOKS:
            nb = self.notebooks.get(stem)
            if nb is not None and not nb.readable:
                continue
            wanted = functions_of_notebook(stem)
            if nb is None and not any(f in self.functions for f in wanted):
                notes.append(Note("no_file", stem=stem))
                continue
            for f in wanted:
                found = self.functions.get(f)
                if found is None:
                    notes.append(Note("missing", nb.filename if nb is not None else None, stem, name=f))
                elif (nb is not None and self.files.get(nb.filename, nb).stem == stem
                      and self.files.get(found.filename, nb).stem != stem):
                    # Its notebook is there, yet the function comes from a file of another question.
                    notes.append(Note("borrowed", stem=stem, name=f, detail=found.origin))
        # A given helper the student wrote is noted once (an earlier year's ransacF has its own note).
        other_year = {n.name for n in self.layout_notes if n.kind == "other_year"}
        notes += [Note("own_helper", name=name, detail=origin) for name, origin in self.own_helpers().items()
                  if name not in other_year]
        return notes + list(self.layout_notes) + list(self.ignored)

    def own_helpers(self) -> dict[str, str]:
        """Each helper the kit gives (``core.manifest.GIVEN_HELPERS``) that a file of the submission
        defines itself -> where (the last file read that defines it): that definition, not the
        kit's, is what the student's code calls."""
        found: dict[str, str] = {}
        for pf in self.files.values():
            for name, origin in pf.functions.items():
                if name in GIVEN_HELPERS:
                    found[name] = origin
        return {name: found[name] for name in GIVEN_HELPERS if name in found}


def own_helper_note(name: str, origin: str = "") -> str:
    """The sentence for a student's own definition of the kit's given helper ``name``."""
    where = f" ({origin})" if origin else ""
    return (f"your own {name}{where} was used in place of the given one: the checks ran your code with it, "
            f"so a mistake in it shows there.")


def _homework_order(name: str) -> tuple:
    order = [f for q in QUESTIONS for f in q.functions]
    return (order.index(name) if name in order else len(order), name)


# ------------------------------------------------------------------------------------------------
# files


def load_submission(path: str | Path, *, stems: Sequence[str] = NOTEBOOKS,
                    limits: SizeLimits = SizeLimits()) -> Submission:
    """Read the submission at ``path`` (a folder or a .zip): every notebook and .py file in it.

    Parameters
    ----------
    path : str or Path
        A folder or a zip archive.  Hidden entries (starting with ".", such as
        ``.ipynb_checkpoints``), ``__MACOSX`` and ``__pycache__`` are ignored; symbolic links
        are never followed.
    stems : sequence of str
        The notebook stems files are matched to (the manifest's by default).
    limits : SizeLimits
        Size bounds.

    Raises
    ------
    SubmissionError
        When ``path`` is neither a folder nor a zip, when the archive has an entry that would
        leave its folder (an absolute path or "..": a zip-slip attempt), or when it is too large.
    """
    path = Path(path)
    links: list[str] = []  # candidate files that are symbolic links: skipped, and the student is told
    if path.is_dir() and not path.is_symlink():
        files = _folder_files(path, limits, links)
    elif path.is_file() and zipfile.is_zipfile(path):
        files = _zip_files(path, limits, links)
    else:
        raise SubmissionError(f"path: expected a folder or a .zip archive, got {str(path)!r}")

    # Which notebook of the manifest each file answers, by its name or its metadata.
    matched: list[tuple[str, str, bytes]] = []
    for name, data in files:
        stem = _stem_of(name, stems)
        if stem is None and name.lower().endswith(".ipynb"):
            meta = notebook_stem(data)  # a renamed notebook still knows which one it is
            stem = meta if meta in stems else None
        matched.append((stem or "", name, data))

    # Reading order: the manifest's notebooks first (the kit's own file name first), then path order.
    def order(entry):
        stem, name, _ = entry
        position = list(stems).index(stem) if stem in stems else len(stems)
        return (position, _preference(name, stem) if stem else (), name)

    parsed: dict[str, ParsedNotebook] = {}
    for stem, name, data in sorted(matched, key=order):
        if name.lower().endswith(".py"):
            parsed[name] = parse_python(data, stem=stem, filename=name)
        else:
            parsed[name] = parse_notebook(data, stem=stem, filename=name)
    ignored = tuple(Note("not_used", name, detail=_LINK_SKIPPED) for name in links)
    return _assemble(path.name, parsed, stems, ignored)


_LINK_SKIPPED = "a symbolic link: links are never followed, so its target was not read"


def _assemble(name: str, files: dict[str, ParsedNotebook], stems: Sequence[str],
              ignored: tuple[Note, ...] = ()) -> Submission:
    """The Submission of the parsed ``files`` (in reading order): modules, choices, units, notes."""
    layout: list[Note] = []
    modules, module_files = _modules(files, layout)

    # Each homework function: every file defining it, and the one used.
    functions: dict[str, FoundFunction] = {}
    order = {fname: k for k, fname in enumerate(files)}
    for q in QUESTIONS:
        for f in q.functions:
            cands = [Candidate(pf.filename, pf.stem or None, pf.functions[f], order[pf.filename],
                               _preference(pf.filename, pf.stem) if pf.stem else (),
                               _count(pf, f))
                     for pf in files.values() if pf.readable and f in pf.functions]
            if not cands:
                continue
            best, why = choose(f, q.id, cands)
            pf = files[best.filename]
            others = tuple(c.origin for c in cands if c is not best)
            functions[f] = FoundFunction(f, q.id, best.filename, best.origin, module_files.get(best.filename),
                                         pf.signatures.get(f), why, others)
            if others:
                layout.append(Note("duplicate", best.filename, q.notebook, name=f, count=len(cands),
                                   detail=f"{why}; also defined in {', '.join(others)}, not used"))

    # The file answering each notebook: by its name or metadata, else where its functions come from.
    notebooks: dict[str, ParsedNotebook] = {}
    for pf in files.values():
        if pf.stem in stems and pf.stem not in notebooks:
            notebooks[pf.stem] = pf
    for stem in stems:
        if stem in notebooks or stem not in NOTEBOOKS:
            continue
        source = next((functions[f].filename for f in functions_of_notebook(stem) if f in functions), None)
        if source is not None:
            notebooks[stem] = replace(files[source], stem=stem, expected=functions_of_notebook(stem))
    wanted = {s: functions_of_notebook(s) if s in NOTEBOOKS else () for s in stems}
    missing = tuple(s for s in stems if s not in notebooks and not any(f in functions for f in wanted[s]))

    # The helper module the course gave, when imported and not shipped.
    for helper in GIVEN_HELPER_MODULES:
        if helper in modules:
            continue
        importers = [pf.filename for pf in files.values() if _imports(pf, helper)]
        if importers:
            modules[helper] = GIVEN_HELPERS_ORIGIN
            layout.append(Note("given_helper", importers[0], name=helper))
    layout += _other_years(files)
    job = _job(files, modules, module_files, functions)
    return Submission(name, notebooks, missing, ignored, dict(files), modules, functions, tuple(layout), job)


def _other_years(files: dict[str, ParsedNotebook]) -> list[Note]:
    """One note for a given helper the student wrote with an earlier year's signature (ransacF without
    the eightpoint argument): the last such definition in reading order, as the one a reader meets."""
    found = [pf for pf in files.values() if pf.readable and another_years_ransacF(pf.signatures.get("ransacF"))]
    if not found:
        return []
    pf = found[-1]
    return [Note("other_year", pf.filename, pf.stem or None, name="ransacF", detail=str(pf.signatures["ransacF"]))]


def _count(pf: ParsedNotebook, function: str) -> int:
    return pf.redefined.get(function, 1)


def _imports(pf: ParsedNotebook, module: str) -> bool:
    """True when a kept statement of ``pf`` imports ``module`` (``import helper``, ``from helper import x``)."""
    for u in pf.units:
        for node in ast.walk(ast.parse(u.source)):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                    and node.module.split(".")[0] == module:
                return True
            if isinstance(node, ast.Import) and any(a.name.split(".")[0] == module for a in node.names):
                return True
    return False


def _modules(files: dict[str, ParsedNotebook], layout: list[Note]) -> tuple[dict[str, str], dict[str, str]]:
    """(module name -> file, file -> its main module name) for the .py files.

    A name claimed by several files goes to the file in the folder holding most .py files (the
    student's code folder), then the shallower, then the first in path order; a note says so.
    A file that no import can name gets a private name of the grader's, so it is loaded all the same.
    """
    py = [pf.filename for pf in files.values() if pf.is_python and pf.readable]
    per_folder: dict[str, int] = {}
    for fname in py:
        folder = str(PurePosixPath(fname).parent)
        per_folder[folder] = per_folder.get(folder, 0) + 1
    claims: dict[str, list[str]] = {}
    for fname in py:
        for mod in module_names(fname):
            claims.setdefault(mod, []).append(fname)
    modules: dict[str, str] = {}
    for mod, owners in claims.items():
        owners.sort(key=lambda f: (-per_folder[str(PurePosixPath(f).parent)], len(PurePosixPath(f).parts), f))
        modules[mod] = owners[0]
        if len(owners) > 1 and "." not in mod:
            layout.append(Note("module_name", owners[0], name=mod,
                               detail=f"the folder holding most of the code; not {', '.join(owners[1:])}"))
    main: dict[str, str] = {}
    for fname in py:
        mine = [m for m in module_names(fname) if modules.get(m) == fname]
        if not mine:
            mine = [private_module_name(fname, modules)]
            modules[mine[0]] = fname
        main[fname] = mine[0]
    return modules, main


def _job(files: dict[str, ParsedNotebook], modules: dict[str, str], main: dict[str, str],
         functions: dict[str, FoundFunction]) -> tuple[SourceUnit, ...]:
    """The units of :meth:`Submission.units` (see there for the order)."""
    units: list[SourceUnit] = []
    packages: set[str] = set()
    for mod, fname in modules.items():
        for k in range(1, mod.count(".") + 1):  # the folders above a nested module are packages
            pkg = mod.rsplit(".", k)[0]
            if pkg not in modules and pkg not in packages:
                packages.add(pkg)
                units.append(SourceUnit(origin=f"folder {pkg.replace('.', '/')}", line=1, source="", module=pkg))
        if fname == GIVEN_HELPERS_ORIGIN:
            units.append(SourceUnit(origin=GIVEN_HELPERS_ORIGIN, line=1, source=GIVEN_HELPER_SOURCE, module=mod))
            continue
        body = [replace(u, module=mod) for u in files[fname].units]
        units += body or [SourceUnit(origin=fname, line=1, source="", module=mod)]
    notebooks = [pf for pf in files.values() if not pf.is_python and pf.readable]
    for pf in notebooks:
        units += pf.units
    for fname, mod in main.items():
        units.append(SourceUnit(origin=fname, line=1, source=f"__import__({mod!r})"))
    for f, found in functions.items():
        if found.module is not None:
            units.append(SourceUnit(origin=found.filename, line=1, source=f"from {found.module} import {f}",
                                    defines=(f,)))
        else:
            units.append([u for u in files[found.filename].units if f in u.defines][-1])
    # Names a module uses and never defines, defined elsewhere: taken from the grader's namespace.
    defined_somewhere = {n for pf in files.values() for n in pf.definitions}
    links = {main[pf.filename]: sorted(pf.free & defined_somewhere)
             for pf in files.values() if pf.filename in main and pf.free & defined_somewhere}
    if links:
        units.append(SourceUnit(origin="the grader (names shared between files)", line=1, source=_LINK.format(links)))
    return tuple(units)


_LINK = """\
def _hw4_link(links):
    import sys
    shared = globals()
    for name, wanted in links.items():
        module = sys.modules.get(name)
        for n in wanted if module is not None else ():
            if n not in vars(module) and n in shared:
                setattr(module, n, shared[n])
_hw4_link({!r})
del _hw4_link
"""


def _is_ignored(name: str) -> bool:
    """Hidden entries, macOS's and Python's leftovers: never read, never mentioned."""
    return any(p.startswith(".") or p == "__MACOSX" or p == "__pycache__" for p in PurePosixPath(name).parts)


def _is_candidate(name: str) -> bool:
    return not _is_ignored(name) and name.lower().endswith((".ipynb", ".py"))


def _folder_files(root: Path, limits: SizeLimits, links: list[str]) -> list[tuple[str, bytes]]:
    # Listed without recursion: a folder thousands of levels deep must not stop the class.
    listing = list_files(root, max_entries=limits.max_entries)
    if listing.truncated:
        raise SubmissionError(f"path: expected at most {limits.max_entries} entries, got more")
    links += [rel for p in listing.links if not _is_ignored(rel := p.relative_to(root).as_posix())]
    out, total = [], 0
    for p, st in listing.files:
        rel = p.relative_to(root).as_posix()
        if not _is_candidate(rel):
            continue
        total += st.st_size
        if total > limits.max_total_bytes:
            raise SubmissionError(f"path: expected at most {limits.max_total_bytes} bytes of notebooks, got more")
        out.append((rel, _TOO_BIG if st.st_size > limits.max_file_bytes else p.read_bytes()))
    return out


_TOO_BIG = b"\x00too-big"  # stands for a file that was not read because of its size


def _zip_files(path: Path, limits: SizeLimits, links: list[str]) -> list[tuple[str, bytes]]:
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
                if is_link and not _is_ignored(name):
                    links.append(name)
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
    return parse_notebook_cells(cells, stem=stem, filename=filename)


def parse_notebook_cells(cells: Iterable[Cell | str], *, stem: str, filename: str) -> ParsedNotebook:
    """Parse code cells (strings are numbered 1, 2, ...) into the units of one ParsedNotebook."""
    parsed, problems = parse_code_cells(cells)
    units: list[SourceUnit] = []
    counts: dict[str, int] = {}
    found: dict[str, str] = {}
    functions: dict[str, str] = {}
    signatures: dict[str, Signature] = {}
    python_file = filename.lower().endswith(".py")
    kept = definitions(parsed, constants=True, links=False, homework=_HOMEWORK)
    for d in kept:
        origin = filename if python_file else f"{filename}, cell {d.cell.number}"
        where = f"{origin}, line {d.lineno}" if python_file else origin
        for name in d.defines:
            counts[name] = counts.get(name, 0) + 1
            found[name] = where
        sig = signature_of(d.node) if d.node is not None else None
        if sig is not None or isinstance(d.node, ast.ClassDef):
            for name in d.defines:
                functions[name] = where
                if sig is not None:
                    signatures[name] = sig
                else:
                    signatures.pop(name, None)
        elif not isinstance(d.node, ast.Import | ast.ImportFrom):
            for name in d.defines:  # rebound to something that is not a function
                functions.pop(name, None)
                signatures.pop(name, None)
        units.append(SourceUnit(origin=origin, line=d.line, source=d.source, future=d.future, defines=d.defines))
    redefined = {n: c for n, c in counts.items() if c > 1}
    free = frozenset(free_globals([d.node for d in kept if d.node is not None], set(found)))
    return ParsedNotebook(stem, filename, True, None, tuple(units), tuple(problems), found,
                          redefined, _expected(stem), functions, signatures, free)


def _expected(stem: str) -> tuple[str, ...]:
    return functions_of_notebook(stem) if stem in NOTEBOOKS else ()
