"""Rank the pairs of submissions whose code of one homework function looks alike, and group them.

For every function of the manifest, each submission's definition is fingerprinted
(``fingerprint``), the handout's code (the stubs of the student notebooks and the starter
package) is subtracted, and every pair is compared at once with one matrix product:

- ``shared`` is the number of fingerprints the two have in common, ``jaccard`` that over the
  size of their union, ``containment`` that over the smaller of the two (one copy padded with
  extra lines still scores high);
- ``score = max(jaccard, containment - 0.15) * min(1, shared / MIN_SHARED)``: alike *and*
  enough code to say so.  Two one-line ``return K2.T @ F @ K1`` are identical yet say nothing.

Only the handout explains code away.  A fingerprint is not discounted for being common in the
batch: in a small batch, five copies of one solution are most of it, and a discount by how
many submissions share a line would cancel exactly the code that should be found.  The textbook
lines that independent students share (``U, S, Vt = np.linalg.svd(F)``) are a few short units
of a function, which the Jaccard share and ``MIN_SHARED`` absorb.

Pairs at or above ``FLAG`` are listed as "look at these", and ``groups`` joins the submissions
linked by flagged pairs (of any function) into groups, so that N copies of one solution are one
group of N, not N(N-1)/2 pairs to read.  The score ranks; the staff decide.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from core.paths import KIT_ROOT, NOTEBOOKS_DIR

from .fingerprint import Fingerprints, fingerprint_code, fingerprint_function
from .reader import FUNCTIONS, FunctionSource, SubmissionCode, stub_sources

__all__ = ["FLAG", "MIN_SHARED", "FunctionComparison", "Group", "Pair", "compare", "given_hashes", "groups"]

FLAG = 0.5
MIN_SHARED = 24.0  # about three statements: a fingerprint per unit plus its winnowed k-grams
CONTAINMENT_DISCOUNT = 0.15


@dataclass(frozen=True)
class Pair:
    """Two submissions' code of one function, compared.

    a, b: submission names (a < b); score: the ranking figure in [0, 1]; jaccard, containment:
    shares of alike code (see the module's docstring); shared: how many fingerprints they share;
    flagged: score >= FLAG; rank: 1 for the most alike pair of the function.
    """

    function: str
    a: str
    b: str
    score: float
    jaccard: float
    containment: float
    shared: float
    flagged: bool
    rank: int

    def as_dict(self) -> dict:
        return {"function": self.function, "rank": self.rank, "a": self.a, "b": self.b,
                "score": round(self.score, 4), "jaccard": round(self.jaccard, 4),
                "containment": round(self.containment, 4), "shared": round(self.shared, 2),
                "flagged": self.flagged}


@dataclass
class FunctionComparison:
    """Every pair of the submissions that define ``function``.

    names: the submissions compared (n); fingerprints: their Fingerprints, the handout's code
    removed; score, jaccard, containment, shared: (n, n) symmetric float arrays; skipped:
    submissions without this function (or with nothing of their own in it).
    """

    function: str
    names: list
    fingerprints: list
    score: np.ndarray
    jaccard: np.ndarray
    containment: np.ndarray
    shared: np.ndarray
    skipped: list = field(default_factory=list)

    def ranked(self, limit: int | None = None, *, flagged_too: bool = True) -> list[Pair]:
        """Pairs best first (ties by names); at most ``limit`` of them, plus, beyond that when
        ``flagged_too``, the flagged pairs that link each submission to its group (the strongest
        links first, as in a maximum spanning forest): N copies of one solution are listed as
        N - 1 pairs, not N(N-1)/2, and every member of every group is in the list."""
        n = len(self.names)
        if n < 2:
            return []
        iu, ju = np.triu_indices(n, 1)
        s = self.score[iu, ju]
        order = np.lexsort((ju, iu, -s))
        chosen = list(enumerate(order[:limit]))  # (rank - 1, pair index): all of them without a limit
        if limit is not None and flagged_too:
            parent = list(range(n))

            def root(x: int) -> int:
                while parent[x] != x:
                    parent[x] = parent[parent[x]]
                    x = parent[x]
                return x

            for pos, k in enumerate(order[:int(np.sum(s >= FLAG))]):
                a, b = root(int(iu[k])), root(int(ju[k]))
                if a != b:
                    parent[a] = b
                    if pos >= limit:
                        chosen.append((pos, k))
        out = []
        for pos, k in chosen:
            i, j = int(iu[k]), int(ju[k])
            a, b = sorted((self.names[i], self.names[j]))
            out.append(Pair(self.function, a, b, float(self.score[i, j]), float(self.jaccard[i, j]),
                            float(self.containment[i, j]), float(self.shared[i, j]),
                            bool(self.score[i, j] >= FLAG), pos + 1))
        return out

    def pair_score(self, a: str, b: str) -> float:
        i, j = self.names.index(a), self.names.index(b)
        return float(self.score[i, j])

    def matching_lines(self, a: str, b: str) -> tuple[set[int], set[int]]:
        """Lines (1-based in each function's source) of a and of b that carry a common fingerprint."""
        fa = self.fingerprints[self.names.index(a)]
        fb = self.fingerprints[self.names.index(b)]
        common = {h for h, _ in fa.hashes & fb.hashes}
        return _lines(fa, common), _lines(fb, common)


def _lines(fp: Fingerprints, hashes) -> set[int]:
    out = set()
    for h in hashes:
        for first, last in fp.lines.get(h, ()):
            out.update(range(first, last + 1))
    return out


def given_hashes(notebooks_dir: str | Path | None = NOTEBOOKS_DIR,
                 extra_dirs: Sequence[str | Path] = (KIT_ROOT / "starter",)) -> set[int]:
    """Plain hashes of the handout's code: the student notebooks' cells (the stubs) and every
    .py file under ``extra_dirs`` (the starter package students import and may paste from)."""
    given: set[int] = set()
    sources = stub_sources(notebooks_dir) if notebooks_dir else []
    for d in extra_dirs:
        for p in sorted(Path(d).rglob("*.py")):
            sources.append(FunctionSource("<file>", p.read_text(errors="replace"), str(p), 1))
    for fs in sources:
        given |= code_hashes(fs.source)
    return given


def code_hashes(source: str) -> set[int]:
    """Plain hashes of one piece of code (empty when it does not parse): the whole, and each of its
    functions also as written on its own (its names bound locally)."""
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return set()
    out = {h for h, _ in fingerprint_code(tree).hashes}
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            out.update(h for h, _ in fingerprint_code(node).hashes)
    return out


def compare_function(function: str, items: Iterable[tuple[str, Fingerprints]]) -> FunctionComparison:
    """Compare every pair of ``items`` (submission name, fingerprints without the handout's code)."""
    items = list(items)
    names = [name for name, _ in items]
    if len(set(names)) != len(names):
        raise ValueError(f"items: expected distinct submission names, got {names}")
    fps = [fp for _, fp in items]
    n = len(items)
    sizes = np.array([len(fp.hashes) for fp in fps], float)
    # columns: (hash, repeat) keys found in two submissions or more (the others are in no pair)
    counts: dict[tuple, int] = {}
    for fp in fps:
        for key in fp.hashes:
            counts[key] = counts.get(key, 0) + 1
    cols = {key: k for k, key in enumerate(key for key, c in counts.items() if c >= 2)}
    X = np.zeros((n, len(cols)), dtype=np.float32)
    for i, fp in enumerate(fps):
        X[i, [cols[key] for key in fp.hashes if key in cols]] = 1.0
    shared = (X @ X.T).astype(float) if len(cols) else np.zeros((n, n))
    np.fill_diagonal(shared, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        union = sizes[:, None] + sizes[None, :] - shared
        jac = np.where(union > 0, shared / union, 0.0)
        small = np.minimum(sizes[:, None], sizes[None, :])
        con = np.where(small > 0, shared / small, 0.0)
    score = np.maximum(jac, con - CONTAINMENT_DISCOUNT) * np.minimum(1.0, shared / MIN_SHARED)
    score = np.clip(score, 0.0, 1.0)
    np.fill_diagonal(score, 0.0)
    return FunctionComparison(function, names, fps, score, jac, con, shared)


def compare(submissions: Sequence[SubmissionCode], given: set[int] | None = None,
            functions: Sequence[str] = FUNCTIONS) -> dict[str, FunctionComparison]:
    """One FunctionComparison per function of ``functions``; ``given`` defaults to ``given_hashes()``."""
    if given is None:
        given = given_hashes()
    unknown = [f for f in functions if f not in FUNCTIONS]
    if unknown:
        raise ValueError(f"functions: expected names among {list(FUNCTIONS)}, got {unknown}")
    out = {}
    for function in functions:
        items, skipped = [], []
        for sub in submissions:
            fs = sub.functions.get(function)
            fp = None
            if fs is not None:
                try:
                    fp = fingerprint_function(fs.source).without(given)
                except (SyntaxError, ValueError):
                    fp = None
            if fp is None or not fp.hashes:
                skipped.append(sub.name)
            else:
                items.append((sub.name, fp))
        comp = compare_function(function, items)
        comp.skipped = skipped
        out[function] = comp
    return out


@dataclass(frozen=True)
class Group:
    """Submissions linked by flagged pairs, in any function: one group to look at together.

    members: sorted submission names (two or more); functions: function -> the highest score of
    a flagged pair inside the group in that function (only functions with one); pairs: how many
    flagged pairs link them, over all functions.
    """

    members: tuple
    functions: dict
    pairs: int

    def as_dict(self) -> dict:
        return {"members": list(self.members), "functions": {f: round(s, 4) for f, s in self.functions.items()},
                "pairs": self.pairs}


def groups(comparisons: dict[str, FunctionComparison]) -> list[Group]:
    """The groups of ``comparisons`` (function -> FunctionComparison), largest first (ties by names).

    Linked means joined by a chain of flagged pairs, so a group may hold two submissions that were
    not flagged together (each alike to a third): the functions and scores say where to look.
    """
    parent: dict[str, str] = {}

    def root(x: str) -> str:
        while parent.setdefault(x, x) != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    flagged = []
    for function, comp in comparisons.items():
        for i, j in zip(*np.nonzero(np.triu(comp.score >= FLAG, 1))):
            a, b = comp.names[int(i)], comp.names[int(j)]
            flagged.append((function, a, b, float(comp.score[i, j])))
            parent[root(a)] = root(b)
    members: dict[str, list] = {}
    for x in list(parent):
        members.setdefault(root(x), []).append(x)
    found: dict[str, tuple[dict, list]] = {r: ({}, [0]) for r in members}
    for function, a, b, s in flagged:
        functions, count = found[root(a)]
        functions[function] = max(s, functions.get(function, 0.0))
        count[0] += 1
    out = [Group(tuple(sorted(members[r])), {f: functions[f] for f in comparisons if f in functions}, count[0])
           for r, (functions, count) in found.items()]
    return sorted(out, key=lambda g: (-len(g.members), g.members))
