"""Steps 1 and 2 of the notebook build: read a source (notebooks/src/<stem>.md) into blocks, and
take a reference function of solutions/ apart (its contract, body, helpers and imports).

The source format is described in the package docstring (kit/notebooks/__init__.py).
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from pathlib import Path

from core.manifest import QUESTION_HEADING, QUESTIONS, Question
from core.paths import KIT_ROOT

SRC_DIR = KIT_ROOT / "notebooks" / "src"
SOLUTIONS_DIR = KIT_ROOT / "solutions"

BARE_HEADING = re.compile(r"^(#{1,3})\s*(Q\d+(?:\.\d+)?)\s*$")
_FENCE = re.compile(r"^```(python|\{(\w+)\})[ \t]*(.*)$")


# What a "+++ WORD" line says about the markdown cell after it: it starts a printed page, or it
# is the kit's plumbing (how to work on Colab...), left out of the PDF.
MARKDOWN_MARKS = ("page", "plumbing")


class SourceError(ValueError):
    """A notebook source or a solution module breaks the rules of this module (says where)."""


# ------------------------------------------------------------------------ step 1: the source


@dataclass(frozen=True)
class Block:
    """One cell of a source file.

    kind: "markdown", "python", or a directive ("colab", "setup", "solution", "check", "answer");
    args: the words after the fence (a markdown block after ``+++ page``: ("page",), after
    ``+++ plumbing``: ("plumbing",)); text: the content; line: where it starts (1-based).
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
    mark = None  # how the next markdown block prints: "page" or "plumbing" (a "+++ WORD" line)

    def flush(next_line: int):
        nonlocal md, md_start, mark
        body = "\n".join(md).strip("\n")
        if body.strip():
            blocks.append(Block("markdown", (mark,) if mark else (), body, md_start))
            mark = None
        md, md_start = [], next_line

    i = 0
    while i < len(lines):
        line, lineno = lines[i], i + 1
        m = None if in_md_fence else _FENCE.match(line)
        if m:
            flush(lineno)
            kind = "python" if m.group(1) == "python" else m.group(2)
            if mark:
                raise SourceError(f"{name}, line {lineno}: '+++ {mark}' must be followed by a markdown cell")
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
        elif not in_md_fence and line.split() and line.split()[0] == "+++":
            words = line.split()[1:]
            if len(words) > 1 or (words and words[0] not in MARKDOWN_MARKS):
                raise SourceError(f"{name}, line {lineno}: expected '+++' or '+++ WORD' with WORD one of "
                                  f"{list(MARKDOWN_MARKS)}, got {line.strip()!r}")
            flush(lineno + 1)
            mark = words[0] if words else mark
        elif not in_md_fence and BARE_HEADING.match(line):
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


def heading_text(q: Question, hashes: str) -> str:
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


def referenced_names(nodes) -> tuple[set[str], set[str]]:
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


def find_module(name: str, solutions_dir: Path) -> Path:
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
    path = find_module(name, solutions_dir)
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
        names, _ = referenced_names([queue.pop()])
        for n in sorted(names):
            if n in _ALL_FUNCTIONS and n != name:
                needs.add(n)
            elif n in defs and n != name and n not in needed and n not in _ALL_FUNCTIONS:
                needed.append(n)
                queue.append(defs[n])
    order = list(defs)
    helpers = [h for h in order if h in needed]
    names, dotted = referenced_names([fn] + [defs[h] for h in helpers])
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
