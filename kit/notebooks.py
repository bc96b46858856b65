"""Build the homework notebooks from one source: the student version, the answer key, the nbgrader source.

Two inputs, each written once:

- ``solutions/*.py``: the reference functions.  Their signature and docstring (the shape
  contract) go to every version; their body only to the answer key (verbatim) and to the
  nbgrader source (between ``### BEGIN SOLUTION`` / ``### END SOLUTION``).
- ``notebooks/src/<stem>.md``: the text and the figure cells of each notebook, in the format
  below; ``notebooks/src/settings.json`` holds the course repository the notebooks point to.

Source format
-------------
Markdown, split into cells by a line ``+++`` and before every question heading.  A question
heading is written bare (``## Q3.2``); the builder completes it from ``core.manifest``
(``## Q3.2 Triangulation [10 points]``), so titles and points live in one place.  Fenced blocks
opened by these lines become special cells (any other fence stays markdown):

``` ```python [tag ...]``      a code cell, the same in every version (tags go to the cell
                               metadata; ``figure`` marks a cell whose output must be an image).
                               ``### BEGIN SOLUTION`` / ``### END SOLUTION`` lines inside work
                               as in nbgrader: the key drops the markers, the student version
                               gets the nbgrader stub instead of the region.
``` ```{colab}``               the "Open in Colab" link.
``` ```{setup}``               the first code cell: finds (locally) or fetches (Colab) the kit.
``` ```{solution} name``       the stub / reference / nbgrader cell of function ``name``.
``` ```{check} name``          the self-check cell ``check_<name>(<name>)`` from
                               ``starter.checks.<module of name in solutions/>``.
``` ```{answer} Q1.1 [points=N]`` a written answer graded by hand: the block is the key's answer.
                               ``ungraded`` instead of ``points=N``: read from the PDF only, no
                               nbgrader points (the autograded cells keep the question's points).

In the nbgrader source a function's imports and module-level helpers go inside its region,
nested in the function, because nbgrader replaces a region by a stub that must still run; the
answer key keeps them at the top level, as in solutions/.

Points: each check and answer cell under a question heading is graded (nbgrader); explicit
``points=`` are kept and the rest of the question's points are shared by the others.

Order of the steps (each a small function below): parse the source -> expand bare headings ->
turn blocks into cells for one version -> attach nbgrader metadata (nbgrader source only) ->
assemble and validate the notebook -> write it.
"""

from __future__ import annotations

import ast
import json
import re
import textwrap
from dataclasses import dataclass, field
from pathlib import Path

import nbformat

from core.manifest import (
    NOTEBOOKS,
    QUESTION_HEADING,
    QUESTIONS,
    Question,
    functions_of_notebook,
)
from core.notebook import METADATA_KEY

__all__ = [
    "ANSWER_PLACEHOLDER",
    "KIT_ROOT",
    "NBGRADER_STUB",
    "VARIANTS",
    "Block",
    "Extracted",
    "Settings",
    "add_cli",
    "build_all",
    "build_notebook",
    "extract_function",
    "load_settings",
    "outdated",
    "output_path",
    "parse_source",
    "settings_of",
    "write_all",
]

KIT_ROOT = Path(__file__).resolve().parents[1]
SRC_DIR = KIT_ROOT / "notebooks" / "src"
SOLUTIONS_DIR = KIT_ROOT / "solutions"

VARIANTS = ("student", "key", "nbgrader")
OUT_DIRS = {"student": Path("notebooks"), "key": Path("notebooks") / "key",
            "nbgrader": Path("notebooks") / "nbgrader" / "source" / "hw4"}
# Exactly what nbgrader's ClearSolutions writes, so its release of our nbgrader source and our
# student notebooks hold the same code.
NBGRADER_STUB = "# YOUR CODE HERE\nraise NotImplementedError()"
ANSWER_PLACEHOLDER = "YOUR ANSWER HERE"
PLACEHOLDER_REPO = "https://github.com/YOUR-ORG/YOUR-HW4-RELEASE"
BEGIN, END = "### BEGIN SOLUTION", "### END SOLUTION"

_BARE_HEADING = re.compile(r"^(#{1,3})\s*(Q\d+(?:\.\d+)?)\s*$")
_FENCE = re.compile(r"^```(python|\{(\w+)\})[ \t]*(.*)$")
_GITHUB = re.compile(r"^https://github\.com/([A-Za-z0-9_.-]+)/([A-Za-z0-9_.-]+?)(?:\.git)?/?$")
_LOCAL_GIT = re.compile(r"^file:///[^\s\"'\\]+$")


class SourceError(ValueError):
    """A notebook source or a solution module breaks the rules of this module (says where)."""


# --------------------------------------------------------------------------------- settings


@dataclass(frozen=True)
class Settings:
    """Where the published student kit lives.

    repo_url: the GitHub repository of the student release (``python -m kit release``), e.g.
    ``https://github.com/cmu-16720/hw4``, or a local git repository ``file:///path`` (tests, a
    course server): the setup cell clones it, but Colab cannot open notebooks from it, so the
    notebooks then carry no "Open in Colab" link.  ref: the branch or tag to open and to clone.
    The placeholder (:data:`PLACEHOLDER_REPO`) is accepted only for the kit's own committed build;
    anything given to students refuses it (:meth:`require_repository`).
    """

    repo_url: str = PLACEHOLDER_REPO
    ref: str = "main"

    def __post_init__(self):
        if not (_GITHUB.match(self.repo_url) or _LOCAL_GIT.match(self.repo_url)):
            raise ValueError(f"repo_url: expected a GitHub repository URL like https://github.com/ORG/REPO "
                             f"(Colab opens notebooks from GitHub) or a local git repository file:///PATH, "
                             f"got {self.repo_url!r}")
        if not re.fullmatch(r"[A-Za-z0-9_./-]+", self.ref) or self.ref.startswith("-"):
            raise ValueError(f"ref: expected a branch or tag name, got {self.ref!r}")

    @property
    def is_placeholder(self) -> bool:
        return self.repo_url == PLACEHOLDER_REPO

    def require_repository(self, what: str) -> "Settings":
        """These settings, or a ValueError saying how to name the repository when they hold the placeholder."""
        if self.is_placeholder:
            raise ValueError(
                f"repo_url: {what} needs the repository students get the kit from, got the placeholder "
                f"{PLACEHOLDER_REPO}. Pass --repo-url https://github.com/ORG/REPO (the public GitHub "
                f"repository you push the release to; --ref BRANCH if not main), or set repo_url in "
                f"notebooks/src/settings.json. The notebooks' Colab links and setup cells point there.")
        return self

    def colab_url(self, stem: str) -> str | None:
        """The "Open in Colab" address of a student notebook; None for a repository Colab cannot open."""
        m = _GITHUB.match(self.repo_url)
        if m is None:
            return None
        owner, repo = m.groups()
        return f"https://colab.research.google.com/github/{owner}/{repo}/blob/{self.ref}/notebooks/{stem}.ipynb"


def load_settings(path: Path | None = None) -> Settings:
    """The settings in ``notebooks/src/settings.json`` (defaults when the file is absent)."""
    path = Path(path) if path is not None else SRC_DIR / "settings.json"
    if not path.exists():
        return Settings()
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except ValueError as exc:
        raise ValueError(f"{path}: expected JSON with repo_url and ref ({exc})") from None
    unknown = set(data) - {"repo_url", "ref", "comment"}
    if unknown:
        raise ValueError(f"{path}: expected the keys repo_url, ref (and comment), got also {sorted(unknown)}")
    return Settings(data.get("repo_url", PLACEHOLDER_REPO), data.get("ref", "main"))


def settings_of(nb: nbformat.NotebookNode) -> Settings:
    """The settings a built notebook was made with (from its metadata)."""
    meta = nb.metadata.get(METADATA_KEY, {})
    return Settings(meta.get("repo_url", PLACEHOLDER_REPO), meta.get("ref", "main"))


# ------------------------------------------------------------------------ step 1: the source


@dataclass(frozen=True)
class Block:
    """One cell of a source file.

    kind: "markdown", "python", or a directive ("colab", "setup", "solution", "check", "answer");
    args: the words after the fence; text: the content; line: where it starts (1-based).
    """

    kind: str
    args: tuple[str, ...]
    text: str
    line: int


def parse_source(text: str, name: str = "<source>") -> list[Block]:
    """Split a notebook source (format in the module docstring) into blocks.

    Raises SourceError naming ``name`` and the line for an unclosed fence or a question heading
    written out in full.
    """
    lines = text.splitlines()
    blocks: list[Block] = []
    md: list[str] = []
    md_start = 1
    in_md_fence = False

    def flush(next_line: int):
        nonlocal md, md_start
        body = "\n".join(md).strip("\n")
        if body.strip():
            blocks.append(Block("markdown", (), body, md_start))
        md, md_start = [], next_line

    i = 0
    while i < len(lines):
        line, lineno = lines[i], i + 1
        m = None if in_md_fence else _FENCE.match(line)
        if m:
            flush(lineno)
            kind = "python" if m.group(1) == "python" else m.group(2)
            body = []
            i += 1
            while i < len(lines) and lines[i].rstrip() != "```":
                body.append(lines[i])
                i += 1
            if i == len(lines):
                raise SourceError(f"{name}, line {lineno}: the ``` block opened here is never closed")
            blocks.append(Block(kind, tuple(m.group(3).split()), "\n".join(body).strip("\n"), lineno))
            md_start = i + 2
        elif line.startswith("```"):
            in_md_fence = not in_md_fence
            md.append(line)
        elif not in_md_fence and line.strip() == "+++":
            flush(lineno + 1)
        elif not in_md_fence and _BARE_HEADING.match(line):
            flush(lineno)
            md.append(line)
        else:
            if not in_md_fence and re.match(QUESTION_HEADING, line):
                raise SourceError(f"{name}, line {lineno}: write the question heading bare ('## Q2'); "
                                  f"the title and points come from core.manifest, got {line!r}")
            md.append(line)
        i += 1
    flush(len(lines) + 1)
    return blocks


def _heading_text(q: Question, hashes: str) -> str:
    points = f"{q.points} points" + (", extra credit" if q.extra_credit else "")
    return f"{hashes} {q.id} {q.title} [{points}]"


# ------------------------------------------------------------- step 2: the reference functions


@dataclass(frozen=True)
class Extracted:
    """A reference function taken apart.

    name, module (e.g. "fundamental"); source: the def verbatim (decorators to last line);
    header: the def line(s) and the docstring; body: the lines after the docstring;
    helpers: (name, source) of the module-level helpers it needs, in module order;
    imports: the module's import statements it (or its helpers) uses, trimmed to those names;
    needs: other homework functions it calls (defined in the same or another notebook);
    contract: what students see of the def: ``header`` without the reference's keyword-only
    parameters (the kit's own switches, never the handout's) and without the docstring's
    ``METHOD_SECTION`` and everything after it;
    switches: ``name = default`` for each keyword-only parameter, which the nbgrader region
    binds so that the body still runs under the handout's signature.
    """

    name: str
    module: str
    source: str
    header: str
    body: str
    helpers: tuple[tuple[str, str], ...]
    imports: tuple[str, ...]
    needs: tuple[str, ...]
    contract: str = ""
    switches: tuple[str, ...] = ()


# The docstring heading (numpy style, underlined) from which a reference docstring is the answer
# key's only: the method, formulas and tuned constants.  Students get the docstring above it.
METHOD_SECTION = "Method (answer key only)"


_ALL_FUNCTIONS = tuple(f for q in QUESTIONS for f in q.functions)


def _referenced(nodes) -> tuple[set[str], set[str]]:
    """Names loaded, and dotted prefixes of attribute chains ("scipy", "scipy.optimize"), in nodes."""
    names, dotted = set(), set()
    for node in nodes:
        for n in ast.walk(node):
            if isinstance(n, ast.Name):
                names.add(n.id)
            elif isinstance(n, ast.Attribute):
                parts = []
                cur = n
                while isinstance(cur, ast.Attribute):
                    parts.append(cur.attr)
                    cur = cur.value
                if isinstance(cur, ast.Name):
                    chain = [cur.id] + parts[::-1]
                    dotted.update(".".join(chain[:k]) for k in range(1, len(chain) + 1))
    return names, dotted


def _lines(text: str, node: ast.AST) -> list[str]:
    start = min([node.lineno] + [d.lineno for d in getattr(node, "decorator_list", [])])
    return text.splitlines()[start - 1:node.end_lineno]


def _module_parts(path: Path):
    text = path.read_text(encoding="utf-8")
    tree = ast.parse(text, filename=str(path))
    defs, imports = {}, []
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            defs[node.name] = node
        elif isinstance(node, ast.Assign):
            for t in node.targets:
                if isinstance(t, ast.Name) and t.id != "__all__":
                    defs[t.id] = node
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            imports.append(node)
    return text, defs, imports


def _find_module(name: str, solutions_dir: Path) -> Path:
    hits = []
    for path in sorted(solutions_dir.glob("*.py")):
        if path.name == "__init__.py":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        if any(isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) and n.name == name for n in tree.body):
            hits.append(path)
    if len(hits) != 1:
        raise SourceError(f"name: expected exactly one module of {solutions_dir} to define {name}, "
                          f"found {[p.name for p in hits] or 'none'}")
    return hits[0]


def extract_function(name: str, solutions_dir: Path | None = None) -> Extracted:
    """Take the reference function ``name`` apart (see :class:`Extracted`).

    Raises SourceError when no (or more than one) module defines it, when it has no docstring,
    or when it imports from a sibling module something that is not a homework function.
    """
    solutions_dir = Path(solutions_dir) if solutions_dir is not None else SOLUTIONS_DIR
    path = _find_module(name, solutions_dir)
    text, defs, imports = _module_parts(path)
    fn = defs[name]
    if not (fn.body and isinstance(fn.body[0], ast.Expr) and isinstance(fn.body[0].value, ast.Constant)
            and isinstance(fn.body[0].value.value, str)):
        raise SourceError(f"{path.name}: {name} has no docstring, and its docstring is the shape contract "
                          "every version of the notebook shows")
    if len(fn.body) < 2:
        raise SourceError(f"{path.name}: {name} has a docstring but no code")
    # Helpers are the module's other top-level definitions it reaches, directly or through others.
    needed, queue, needs = [], [fn], set()
    while queue:
        names, _ = _referenced([queue.pop()])
        for n in sorted(names):
            if n in _ALL_FUNCTIONS and n != name:
                needs.add(n)
            elif n in defs and n != name and n not in needed and n not in _ALL_FUNCTIONS:
                needed.append(n)
                queue.append(defs[n])
    order = list(defs)
    helpers = [h for h in order if h in needed]
    names, dotted = _referenced([fn] + [defs[h] for h in helpers])
    kept = []
    for node in imports:
        if isinstance(node, ast.ImportFrom) and node.module == "__future__":
            continue
        if isinstance(node, ast.ImportFrom) and (node.level > 0 or (node.module or "").split(".")[0] == "solutions"):
            strange = [a.name for a in node.names if a.name not in _ALL_FUNCTIONS]
            if strange:
                raise SourceError(f"{path.name}: imports {strange} from another solutions module; only "
                                  f"homework functions may be shared (the notebooks have no solutions/)")
            continue
        if isinstance(node, ast.Import):
            aliases = [a for a in node.names if (a.asname or a.name) in (names | dotted)]
        else:
            aliases = [a for a in node.names if (a.asname or a.name) in names]
        if aliases:
            trimmed = type(node)(**{**{f: getattr(node, f) for f in node._fields}, "names": aliases})
            kept.append(ast.unparse(trimmed))
    lines = text.splitlines()
    doc_end = fn.body[0].end_lineno
    start = min([fn.lineno] + [d.lineno for d in fn.decorator_list])
    header = "\n".join(lines[start - 1:doc_end])
    body = "\n".join(lines[doc_end:fn.end_lineno]).strip("\n")
    return Extracted(
        name=name, module=path.stem, source="\n".join(_lines(text, fn)), header=header,
        body=body, helpers=tuple((h, "\n".join(_lines(text, defs[h]))) for h in helpers),
        imports=tuple(kept), needs=tuple(sorted(needs)),
        contract=_contract(fn, lines, path.name), switches=_switches(fn))


def _contract(fn: ast.FunctionDef, lines: list[str], where: str) -> str:
    """The def line(s) and docstring a student sees (see ``Extracted.contract``)."""
    args = fn.args
    if args.kwonlyargs:
        if args.vararg or any(d is None for d in args.kw_defaults):
            raise SourceError(f"{where}: {fn.name}'s keyword-only parameters are the kit's switches and "
                              "need defaults (and no *args), so that the handout's call still works")
        plain = ast.arguments(posonlyargs=args.posonlyargs, args=args.args, vararg=None, kwonlyargs=[],
                              kw_defaults=[], kwarg=args.kwarg, defaults=args.defaults)
        indent = lines[fn.lineno - 1][:len(lines[fn.lineno - 1]) - len(lines[fn.lineno - 1].lstrip())]
        decorators = [line for d in fn.decorator_list for line in lines[d.lineno - 1:d.end_lineno]]
        def_lines = decorators + [f"{indent}def {fn.name}({ast.unparse(plain)}):"]
    else:
        start = min([fn.lineno] + [d.lineno for d in fn.decorator_list])
        def_lines = lines[start - 1:fn.body[0].lineno - 1]
    doc = lines[fn.body[0].lineno - 1:fn.body[0].end_lineno]
    cut = next((i for i, line in enumerate(doc) if line.strip() == METHOD_SECTION), None)
    if cut is not None:
        if cut == 0 or cut + 1 >= len(doc) or set(doc[cut + 1].strip()) != {"-"}:
            raise SourceError(f"{where}: {fn.name}'s {METHOD_SECTION!r} must be a docstring section "
                              "heading (underlined with dashes) after the contract")
        kept = doc[:cut]
        while kept and not kept[-1].strip():
            kept.pop()
        quote = doc[-1].strip()[-3:]
        doc = kept + [doc[-1][:len(doc[-1]) - len(doc[-1].lstrip())] + quote]
    return "\n".join(def_lines + doc)


def _switches(fn: ast.FunctionDef) -> tuple[str, ...]:
    return tuple(f"{a.arg} = {ast.unparse(d)}" for a, d in zip(fn.args.kwonlyargs, fn.args.kw_defaults)
                 if d is not None)


# ------------------------------------------------------------------- step 3: blocks -> cells


def _markdown(text: str, **meta) -> nbformat.NotebookNode:
    return nbformat.v4.new_markdown_cell(text, metadata=meta or {})


def _code(text: str, **meta) -> nbformat.NotebookNode:
    return nbformat.v4.new_code_cell(text, metadata=meta or {})


def _clear_regions(text: str, variant: str, where: str) -> tuple[str, bool]:
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


def _solution_text(ext: Extracted, variant: str, emitted_helpers: set[str]) -> str:
    if variant == "student":
        return ext.contract + "\n" + textwrap.indent(NBGRADER_STUB, "    ")
    if variant == "key":
        new = [(n, s) for n, s in ext.helpers if n not in emitted_helpers]
        emitted_helpers.update(n for n, _ in new)
        names, dotted = _referenced([ast.parse(ext.source)] + [ast.parse(s) for _, s in new])
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


def _setup_text(settings: Settings) -> str:
    return f"""\
# Setup: run this cell first.  It makes the homework kit (starter/, scenes/, data/) importable.
# On your own machine it finds the kit around this notebook.  On Colab it mounts your Google Drive,
# downloads the kit once into your course folder there (MyDrive/hw4/kit) and installs what Colab
# lacks; your notebooks are looked for in MyDrive/hw4 and MyDrive/Colab Notebooks, whatever Colab
# named them ("Copy of ..."), so later notebooks find your earlier functions in any new session.
import importlib.metadata
import importlib.util
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

STUDENT_NAME = "your name"  # <- your name, printed on the cover of your PDF
KIT_REPO = "{settings.repo_url}"
KIT_REF = "{settings.ref}"
COURSE_FOLDER = "hw4"  # Colab: your course folder in Google Drive (MyDrive/hw4)
USE_DRIVE = True  # Colab without Google Drive: False (then nothing is kept when the session ends)

kit_dir = next((p for p in [Path.cwd(), *Path.cwd().parents] if (p / "starter" / "__init__.py").is_file()), None)
if kit_dir is None and "google.colab" in sys.modules:
    from google.colab import output
    content = Path(os.environ.get("HW4_COLAB_ROOT", "/content"))  # Colab's working folder
    if USE_DRIVE:
        from google.colab import drive
        drive.mount(str(content / "drive"))
        course = content / "drive" / "MyDrive" / COURSE_FOLDER
        folders = [course, course.parent / "Colab Notebooks"]
    else:
        course = content / COURSE_FOLDER
        folders = [content, course]
    os.environ["HW4_NOTEBOOKS"] = os.pathsep.join(map(str, folders))  # read by from_notebook and the hand-in
    kit_dir = course / "kit"
    if not (kit_dir / "starter" / "__init__.py").is_file():
        download = course / "kit-download"
        shutil.rmtree(download, ignore_errors=True)
        course.mkdir(parents=True, exist_ok=True)
        subprocess.run(["git", "clone", "--quiet", "--depth", "1", "--branch", KIT_REF, KIT_REPO, str(download)],
                       check=True)
        download.rename(kit_dir)
    missing = []
    for line in (kit_dir / "requirements.txt").read_text().splitlines():
        requirement = line.split("#")[0].strip()
        name = re.split(r"[<>=!~\\[; ]", requirement)[0]
        if name and not requirement.startswith("-") and name != "anywidget":  # anywidget: optional (clicks)
            try:
                importlib.metadata.version(name)
            except importlib.metadata.PackageNotFoundError:
                missing.append(requirement)
    if missing:
        subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", *missing], check=True)
    output.enable_custom_widget_manager()  # the point-picking widgets
    print("your notebooks are read from:", ", ".join(map(str, folders)))
if kit_dir is None and importlib.util.find_spec("starter") is not None:
    kit_dir = Path(importlib.util.find_spec("starter").origin).parents[1]  # an installed kit
if kit_dir is None:
    raise RuntimeError("The homework kit was not found: open this notebook from the kit's notebooks/ folder, "
                       "install the kit (pip install -e .), or run it on Colab.")
if str(kit_dir) not in sys.path:
    sys.path.insert(0, str(kit_dir))
print("homework kit:", kit_dir)"""


def _colab_text(stem: str, settings: Settings) -> str:
    url = settings.colab_url(stem)
    if url is None:
        return (f"*Colab: this kit comes from {settings.repo_url}, which Colab cannot open; upload the "
                "notebook (File > Upload notebook) or run it in Jupyter.*")
    text = (f"[Open this notebook in Colab]({url}), then *File > Save a copy in Drive*: the setup cell "
            "mounts your Google Drive, where later notebooks and the hand-in find this one.")
    if settings.is_placeholder:
        text += ("  \n*(Placeholder link: the instructor sets the course repository with "
                 "`python -m kit release --repo-url https://github.com/ORG/REPO`.)*")
    return text


def _nbgrader_meta(grade_id: str, *, solution: bool, grade: bool, locked: bool, points: int | None = None) -> dict:
    meta = {"grade": grade, "grade_id": grade_id, "locked": locked, "schema_version": 3,
            "solution": solution, "task": False}
    if grade:
        meta["points"] = points
    return {"nbgrader": meta}


# ------------------------------------------------------------------------ step 4: assemble


@dataclass
class _State:
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


def _markdown_block(block: Block, st: _State, where: str) -> list[nbformat.NotebookNode]:
    m = _BARE_HEADING.match(block.text.splitlines()[0])
    if not m:
        return [_markdown(block.text)]
    hashes, qid = m.groups()
    q = next((q for q in QUESTIONS if q.id == qid), None)
    if q is None or q.notebook != st.stem:
        raise SourceError(f"{where}: heading {qid} is not a question of {st.stem} in core.manifest")
    if qid in st.seen_questions:
        raise SourceError(f"{where}: heading {qid} appears twice")
    st.question = q
    st.seen_questions.append(qid)
    rest = block.text.split("\n", 1)[1] if "\n" in block.text else ""
    return [_markdown(_heading_text(q, hashes) + ("\n" + rest if rest else ""))]


def _colab_block(block: Block, st: _State, where: str) -> list[nbformat.NotebookNode]:
    return [_markdown(_colab_text(st.stem, st.settings))]


def _setup_block(block: Block, st: _State, where: str) -> list[nbformat.NotebookNode]:
    if st.code_cells:
        raise SourceError(f"{where}: the setup cell must be the first code cell")
    st.setup_seen = True
    return [_code(_setup_text(st.settings))]


def _python_block(block: Block, st: _State, where: str) -> list[nbformat.NotebookNode]:
    text, marked = _clear_regions(block.text, st.variant, where)
    st.defined |= _bound_names(block.text.replace(BEGIN, "").replace(END, ""), where)
    meta = {"tags": list(block.args)} if block.args else {}
    if marked and st.variant == "nbgrader":
        meta.update(_nbgrader_meta(f"{st.stem}_cell{st.code_cells}", solution=True, grade=False, locked=False))
    return [_code(text, **meta)]


def _solution_block(block: Block, st: _State, where: str) -> list[nbformat.NotebookNode]:
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
    return [_code(_solution_text(ext, st.variant, st.emitted_helpers), **meta)]


def _check_block(block: Block, st: _State, where: str) -> list[nbformat.NotebookNode]:
    (name,) = _one_arg(block, where)
    if name not in st.solutions:
        raise SourceError(f"{where}: check of {name} before (or without) its solution cell")
    module = extract_function(name, st.solutions_dir).module
    cell = _code(_check_text(name, module, st.variant))
    st.graded.setdefault(st.question.id, []).append((cell, f"check_{name}", None, False))
    return [cell]


def _answer_block(block: Block, st: _State, where: str) -> list[nbformat.NotebookNode]:
    qid, *opts = block.args or ("",)
    if st.question is None or qid != st.question.id:
        raise SourceError(f"{where}: answer for {qid!r} under the heading of "
                          f"{st.question.id if st.question else 'no question'}")
    if opts == ["ungraded"]:
        # Read from the PDF only: nbgrader has no ungraded markdown answer, so its source
        # gets the placeholder too (a plain cell there would hand the answer out).
        return [_markdown(block.text if st.variant == "key" else ANSWER_PLACEHOLDER)]
    points = _points_option(opts, where)
    cell = _markdown(ANSWER_PLACEHOLDER if st.variant == "student" else block.text)
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


def _block_to_cells(block: Block, st: _State, where: str) -> list[nbformat.NotebookNode]:
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


def _share_points(st: _State, name: str) -> None:
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


def build_notebook(stem: str, variant: str, settings: Settings | None = None, *,
                   src_dir: Path | None = None, solutions_dir: Path | None = None) -> nbformat.NotebookNode:
    """One notebook, in memory.

    Parameters
    ----------
    stem : a notebook of core.manifest ("q2_eightpoint").
    variant : "student", "key" or "nbgrader".
    settings : the course repository (default: notebooks/src/settings.json).
    src_dir, solutions_dir : where the sources and the reference functions are (tests use copies).

    Raises
    ------
    ValueError
        For an unknown stem or variant.
    SourceError
        When the source breaks a rule: a question of the notebook without heading, a function
        without solution cell, points that do not add up, a code cell before the setup cell...
    """
    if stem not in NOTEBOOKS:
        raise ValueError(f"stem: expected one of {list(NOTEBOOKS)}, got {stem!r}")
    if variant not in VARIANTS:
        raise ValueError(f"variant: expected one of {VARIANTS}, got {variant!r}")
    src_dir = Path(src_dir) if src_dir is not None else SRC_DIR
    settings = settings if settings is not None else load_settings(src_dir / "settings.json")
    path = src_dir / f"{stem}.md"
    if not path.exists():
        raise FileNotFoundError(f"stem: no source {path} for notebook {stem}")
    st = _State(stem, variant, settings, Path(solutions_dir) if solutions_dir is not None else SOLUTIONS_DIR)
    cells = []
    if variant == "key":
        cells.append(_markdown("**Answer key: for the course staff only. Do not share it with students.**"))
    for block in parse_source(path.read_text(encoding="utf-8"), path.name):
        cells += _block_to_cells(block, st, f"{path.name}, line {block.line}")
    _share_points(st, path.name)
    expected = [q.id for q in QUESTIONS if q.notebook == stem]
    if st.seen_questions != expected:
        raise SourceError(f"{path.name}: expected the question headings {expected} in this order, "
                          f"got {st.seen_questions}")
    if sorted(st.solutions) != sorted(functions_of_notebook(stem)):
        raise SourceError(f"{path.name}: expected solution cells for {list(functions_of_notebook(stem))}, "
                          f"got {st.solutions}")
    for k, cell in enumerate(cells):
        cell["id"] = f"{stem}-{k:02d}"
    nb = nbformat.v4.new_notebook(cells=cells)
    nb.metadata = {
        "kernelspec": {"display_name": "Python 3 (ipykernel)", "language": "python", "name": "python3"},
        "language_info": {"name": "python"},
        METADATA_KEY: {"stem": stem, "variant": variant, "repo_url": settings.repo_url, "ref": settings.ref},
    }
    nbformat.validate(nb)
    return nb


def output_path(stem: str, variant: str, root: Path | None = None) -> Path:
    """Where the built notebook goes, under ``root`` (default: the kit)."""
    return (Path(root) if root is not None else KIT_ROOT) / OUT_DIRS[variant] / f"{stem}.ipynb"


def build_all(settings: Settings | None = None, *, root: Path | None = None, src_dir: Path | None = None,
              solutions_dir: Path | None = None) -> dict[Path, nbformat.NotebookNode]:
    """Every notebook of every version, and the hand-in notebook: output path (under ``root``) -> notebook."""
    from handin.hand_in_notebook import HAND_IN_NAME, hand_in_notebook

    built = {output_path(stem, variant, root): build_notebook(stem, variant, settings, src_dir=src_dir,
                                                               solutions_dir=solutions_dir)
             for variant in VARIANTS for stem in NOTEBOOKS}
    hand_in = hand_in_notebook(_setup_text(settings or load_settings()))
    for i, cell in enumerate(hand_in.cells):
        cell["id"] = f"hand-in-{i}"  # fixed, so that a rebuild is identical
    built[output_path(NOTEBOOKS[0], "student", root).parent / HAND_IN_NAME] = hand_in
    return built


def _dumps(nb: nbformat.NotebookNode) -> str:
    return nbformat.writes(nb) + "\n"


def write_all(settings: Settings | None = None, *, root: Path | None = None) -> list[Path]:
    """Build and write every notebook under ``root`` (default: the kit); returns the paths."""
    written = []
    for path, nb in build_all(settings, root=root).items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(_dumps(nb), encoding="utf-8")
        written.append(path)
    return written


def outdated(settings: Settings | None = None, *, root: Path | None = None) -> list[Path]:
    """The notebooks under ``root`` that differ from (or are missing from) a fresh build."""
    return [p for p, nb in build_all(settings, root=root).items()
            if not p.exists() or p.read_text(encoding="utf-8") != _dumps(nb)]


# ------------------------------------------------------------------------------------ CLI


def main(args) -> int:
    base = load_settings()
    settings = Settings(args.repo_url or base.repo_url, args.ref or base.ref)
    root = Path(args.out) if args.out else None
    if args.check:
        stale = outdated(settings, root=root)
        for p in stale:
            print(f"out of date: {p}")
        if not stale:
            print("every notebook matches its source")
        return 1 if stale else 0
    if root is not None:
        # A build outside the kit is made to be handed out: it must name the real repository.
        settings.require_repository("python -m kit notebooks --out")
    for p in write_all(settings, root=root):
        print(f"wrote {p}")
    if settings.is_placeholder:
        print("note: the kit's own notebooks keep the placeholder repository; students get notebooks from "
              "python -m kit release --repo-url https://github.com/ORG/REPO, which rebuilds them with it")
    return 0


def add_arguments(p) -> None:
    """The arguments of ``python -m kit notebooks``."""
    p.add_argument("--repo-url", default=None,
                   help="GitHub repository of the student release (https://github.com/ORG/REPO, or a local "
                        "file:///PATH), for the Colab links and the kit download (default: "
                        "notebooks/src/settings.json; its placeholder is refused with --out)")
    p.add_argument("--ref", default=None, help="branch or tag of that repository (default: settings.json, main)")
    p.add_argument("--out", default=None, help="write under this folder instead of the kit (notebooks/... inside)")
    p.add_argument("--check", action="store_true",
                   help="write nothing; exit 1 when a committed notebook differs from a fresh build")
