"""Fingerprints of Python code that survive renamed variables, reordered statements, comments and formatting.

The code is parsed with ``ast`` (comments and formatting are gone at once) and cut into *units*:
every simple statement, and the header of every compound statement (``for x in ...``,
``if ...``, ``def f(...)``) apart from its body, whose statements are units of their own.
Docstrings are dropped.  Each unit becomes a sequence of tokens:

- node types (``Call``, ``BinOp``, ``MatMult``, ``Subscript`` ...) and attribute names
  (``.svd``, ``.T``), which carry what the code does;
- the function's parameters replaced by their position (``a0`` for the first), so
  ``K2.T @ F @ K1`` and ``K1.T @ F @ K2`` differ whatever the parameters are called;
- other names bound inside the function (assigned variables, loop targets) replaced by
  placeholders ``v0, v1, ...`` numbered by first appearance *within the unit*, so a renamed
  variable changes nothing and the numbering does not depend on what came before;
- free names (``np``, ``len``, ``camera2``) kept as written;
- numbers written canonically (``1`` and ``1.0`` are both ``1``), every string as ``S``.

A unit gives one hash of all its tokens plus the hashes of its k-grams (``k`` tokens in a row),
winnowed (the smallest hash of every ``window`` consecutive k-grams is kept).  k-grams never
cross a unit's boundary, so reordering independent statements leaves the fingerprints as they
were.  A function's fingerprints are a multiset; the n-th repeat of a hash is stored as
``(hash, n)`` so that a multiset becomes a set and repeated lines count as often as they appear.
"""

from __future__ import annotations

import ast
import hashlib
from dataclasses import dataclass

__all__ = ["K", "WINDOW", "Fingerprints", "fingerprint_function", "fingerprint_code", "unit_tokens"]

K = 5
WINDOW = 3

_COMPOUND_BODIES = ("body", "orelse", "finalbody", "handlers", "cases")


@dataclass(frozen=True)
class Fingerprints:
    """The fingerprints of one piece of code.

    hashes: frozenset of (hash, repeat) pairs (see the module's docstring); lines: hash ->
    tuple of (first line, last line) ranges of the units that produced it, 1-based in the
    parsed text; units: how many units the code had.
    """

    hashes: frozenset
    lines: dict
    units: int

    def without(self, given: set) -> Fingerprints:
        """These fingerprints minus every hash in ``given`` (plain hashes, repeats ignored)."""
        kept = frozenset(h for h in self.hashes if h[0] not in given)
        return Fingerprints(kept, {h: r for h, r in self.lines.items() if h not in given}, self.units)


def _hash(tokens) -> int:
    return int.from_bytes(hashlib.blake2b("\x1f".join(tokens).encode(), digest_size=8).digest(), "little")


def _canon_constant(value) -> str:
    if value is None or isinstance(value, bool):
        return repr(value)
    if isinstance(value, (int, float)):
        try:
            return format(float(value), ".6g")
        except OverflowError:
            return "BIGINT"
    if isinstance(value, complex):
        return "COMPLEX"
    if isinstance(value, bytes):
        return "B"
    if value is Ellipsis:
        return "..."
    return "S"


def _bound_names(fn: ast.AST) -> set[str]:
    """Names bound anywhere inside ``fn`` (its arguments included): the ones that get placeholders."""
    bound = set()
    for node in ast.walk(fn):
        if isinstance(node, ast.arg):
            bound.add(node.arg)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, (ast.Store, ast.Del)):
            bound.add(node.id)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and node is not fn:
            bound.add(node.name)
        elif isinstance(node, ast.alias):
            bound.add((node.asname or node.name).split(".")[0])
        elif isinstance(node, ast.ExceptHandler) and node.name:
            bound.add(node.name)
        elif isinstance(node, (ast.Global, ast.Nonlocal)):
            bound.update(node.names)
    return bound


def _params(fn) -> dict[str, str]:
    """The parameters of ``fn`` -> their positional placeholder ("a0", "a1", ...)."""
    a = fn.args
    names = [x.arg for x in (*a.posonlyargs, *a.args, *([a.vararg] if a.vararg else []), *a.kwonlyargs,
                             *([a.kwarg] if a.kwarg else []))]
    return {n: f"a{i}" for i, n in enumerate(names)}


class _Tokens:
    """Emit the tokens of one unit; ``bound`` names become placeholders numbered within the unit."""

    def __init__(self, bound: set[str], params: dict[str, str] | None = None):
        self.bound = bound
        self.numbers: dict[str, str] = dict(params or {})
        self.fixed = len(self.numbers)
        self.out: list[str] = []

    def name(self, ident: str) -> str:
        if ident not in self.bound:
            return ident
        if ident not in self.numbers:
            self.numbers[ident] = f"v{len(self.numbers) - self.fixed}"
        return self.numbers[ident]

    def emit(self, node) -> None:
        if node is None:
            return
        if isinstance(node, list):
            for item in node:
                self.emit(item)
            return
        if isinstance(node, ast.Name):
            self.out.append(self.name(node.id))
        elif isinstance(node, ast.Constant):
            self.out.append(_canon_constant(node.value))
        elif isinstance(node, ast.Attribute):
            self.emit(node.value)
            self.out.append("." + node.attr)
        elif isinstance(node, ast.arg):
            self.out.append(self.name(node.arg))
        elif isinstance(node, ast.keyword):
            self.out.append(f"{node.arg}=" if node.arg else "**")
            self.emit(node.value)
        elif isinstance(node, ast.alias):
            self.out.append(node.name)
            if node.asname:
                self.out.append(self.name(node.asname))
        elif isinstance(node, ast.expr_context):
            return
        elif isinstance(node, ast.JoinedStr):
            self.out.append("S")
        elif isinstance(node, ast.AST):
            self.out.append(type(node).__name__)
            for field_name, value in ast.iter_fields(node):
                if field_name in ("type_comment", "ctx"):
                    continue
                if isinstance(value, (ast.AST, list)):
                    self.emit(value)
                elif field_name in ("name", "module", "attr", "arg") and isinstance(value, str):
                    self.out.append(self.name(value))
                elif isinstance(value, (str, int)) and field_name in ("level",):
                    continue
            self.out.append(")")


def _is_docstring(stmt: ast.stmt) -> bool:
    return isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Constant) and isinstance(stmt.value.value, str)


def _units(stmts, bound: set[str], params: dict[str, str] | None = None):
    """Yield (tokens, first line, last line) for every unit of the statement list ``stmts``."""
    for stmt in stmts:
        if _is_docstring(stmt) or isinstance(stmt, ast.Pass):
            continue
        bodies = [(f, getattr(stmt, f)) for f in _COMPOUND_BODIES if isinstance(getattr(stmt, f, None), list)]
        if not bodies:
            t = _Tokens(bound, params)
            t.emit(stmt)
            yield t.out, stmt.lineno, stmt.end_lineno or stmt.lineno
            continue
        # the header: every field but the bodies
        t = _Tokens(bound, params)
        t.out.append(type(stmt).__name__)
        for field_name, value in ast.iter_fields(stmt):
            if field_name in _COMPOUND_BODIES or field_name in ("type_comment", "returns") and value is None:
                continue
            if isinstance(value, (ast.AST, list)):
                t.emit(value)
            elif field_name == "name" and isinstance(value, str):
                t.out.append(t.name(value))
        header_end = min((b[0].lineno for _, b in bodies if b and hasattr(b[0], "lineno")), default=stmt.lineno)
        yield t.out, stmt.lineno, max(stmt.lineno, header_end - 1)
        for _, body in bodies:
            for item in body:
                if isinstance(item, ast.ExceptHandler):
                    h = _Tokens(bound, params)
                    h.out.append("except")
                    h.emit(item.type)
                    if item.name:
                        h.out.append(h.name(item.name))
                    yield h.out, item.lineno, item.lineno
                    yield from _units(item.body, bound, params)
                elif isinstance(item, ast.stmt):
                    yield from _units([item], bound, params)
                elif hasattr(item, "body"):  # match_case
                    h = _Tokens(bound, params)
                    h.emit(item.pattern)
                    h.emit(item.guard)
                    yield h.out, item.pattern.lineno, item.pattern.lineno
                    yield from _units(item.body, bound, params)


def unit_tokens(code: ast.AST) -> list[tuple[list[str], int, int]]:
    """(tokens, first line, last line) of every unit of ``code`` (a FunctionDef or a Module)."""
    if isinstance(code, (ast.FunctionDef, ast.AsyncFunctionDef)):
        return list(_units([code], _bound_names(code), _params(code)))
    if isinstance(code, ast.Module):
        units = []
        for stmt in code.body:
            if isinstance(stmt, (ast.FunctionDef, ast.AsyncFunctionDef)):
                units.extend(_units([stmt], _bound_names(stmt), _params(stmt)))
            else:
                units.extend(_units([stmt], _bound_names(code)))
        return units
    raise ValueError(f"code: expected an ast.FunctionDef or ast.Module, got {type(code).__name__}")


def _winnow(hashes: list[int], window: int) -> set[int]:
    if len(hashes) <= window:
        return {min(hashes)} if hashes else set()
    return {min(hashes[i:i + window]) for i in range(len(hashes) - window + 1)}


def fingerprint_code(code: ast.AST, *, k: int = K, window: int = WINDOW) -> Fingerprints:
    """The fingerprints of a FunctionDef or a Module (see the module's docstring)."""
    if not (isinstance(k, int) and k >= 1 and isinstance(window, int) and window >= 1):
        raise ValueError(f"k, window: expected positive ints, got {k!r}, {window!r}")
    counts: dict[int, int] = {}
    hashes = set()
    lines: dict[int, list] = {}
    units = unit_tokens(code)
    for tokens, first, last in units:
        unit_hashes = {_hash(["UNIT", *tokens])}
        if len(tokens) > k:
            unit_hashes |= _winnow([_hash(tokens[i:i + k]) for i in range(len(tokens) - k + 1)], window)
        for h in unit_hashes:
            n = counts.get(h, 0)
            counts[h] = n + 1
            hashes.add((h, n))
            lines.setdefault(h, []).append((first, last))
    return Fingerprints(frozenset(hashes), {h: tuple(r) for h, r in lines.items()}, len(units))


def fingerprint_function(source: str, **kw) -> Fingerprints:
    """The fingerprints of the first function defined in ``source`` (lines 1-based in ``source``).

    Raises ValueError when ``source`` defines no function, SyntaxError when it does not parse.
    """
    tree = ast.parse(source)
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            return fingerprint_code(node, **kw)
    raise ValueError("source: expected the text of a function definition, got no def")
