"""How the files of a hand-in fit together: module names, which definition of a function is used, signatures.

A hand-in may be the kit's per-question notebooks, one notebook, the course's ``submission.py``
with ``helper.py``, ``findM2.py`` and ``visualize.py`` (2018-2021), or one ``.py`` file per part
(``q2_1_eightpoint.py``, ``q3_1_essential_matrix.py`` ... 2022-2024), in folders or zips of any
name.  This module holds the pure rules :mod:`autograder.submission.read` applies to them (no file is
read and no code is run here):

- :func:`module_names`: the names a ``.py`` file is importable by inside the sandbox, as on the
  student's machine (its stem, and its folder-relative dotted paths: ``code/submission.py`` is
  ``submission`` and ``code.submission``);
- :func:`file_rank` and :func:`choose`: when a homework function is defined in several files,
  the one used is the file whose name (or notebook stem) matches the function's question, else
  the last one defined in reading order, and the reason is said in words;
- :func:`signature_of`: a function's parameters, read from its syntax tree, so the grader can
  recognise another course year's signature (the rules: ``judging.conventions``, shared with the
  public self-checks; :func:`another_years_ransacF` for a helper the kit gives and earlier years
  had students write);
- :data:`GIVEN_HELPER_SOURCE`: the body of the ``helper`` (and ``helpers``, ``util``) module a student
  imports without shipping it: the kit's given helpers (``starter``).
"""

from __future__ import annotations

import ast
import builtins
import keyword
import re
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import PurePosixPath

from core.manifest import QUESTIONS
from judging.conventions import Signature, another_years_ransacF

__all__ = [
    "GIVEN_HELPER_MODULES",
    "GIVEN_HELPER_SOURCE",
    "Candidate",
    "Signature",
    "another_years_ransacF",
    "choose",
    "file_label",
    "file_rank",
    "free_globals",
    "module_names",
    "private_module_name",
    "signature_of",
]

# The names the course's helper file had (helper.py; Fall 2023 gave it as util.py); a student who
# imports one without shipping it gets the kit's given helpers (refineF, camera2, ransacF,
# rodrigues, invRodrigues, displayEpipolarF, epipolarMatchGUI, and the course file's _singularize,
# toHomogenous, calc_epi_error, _epipoles).
GIVEN_HELPER_MODULES = ("helper", "helpers", "util")
GIVEN_HELPER_SOURCE = '''\
from starter import *
from starter import __all__
from starter.epipolar import enforce_rank2 as _singularize


def toHomogenous(pts):
    """(N, 2) points -> (N, 3) homogeneous points (a 1 appended to each)."""
    import numpy as np

    pts = np.asarray(pts, dtype=float)
    return np.hstack([pts, np.ones((pts.shape[0], 1))])


def calc_epi_error(pts1_homo, pts2_homo, F):
    """(N,) symmetric squared epipolar distance of each match (pixels^2): x2 to F x1 plus x1 to F^T x2."""
    import numpy as np

    x1, x2, F = np.asarray(pts1_homo, float), np.asarray(pts2_homo, float), np.asarray(F, float)
    l2, l1 = x1 @ F.T, x2 @ F
    r = np.sum(x2 * l2, axis=1) ** 2
    return r / (l2[:, 0] ** 2 + l2[:, 1] ** 2) + r / (l1[:, 0] ** 2 + l1[:, 1] ** 2)


def _epipoles(E):
    """The epipoles (3,) of image 1 and image 2: right and left null vectors of E (or F)."""
    import numpy as np

    U, S, Vt = np.linalg.svd(np.asarray(E, dtype=float))
    return Vt[-1, :], U[:, -1]
'''

# Top-level names a student's module never takes over (the standard library, the kit's packages
# and the libraries of the sandbox): the sandbox's own module wins, as the importer runs last.
_RESERVED = frozenset(sys.stdlib_module_names) | {
    "core", "scenes", "starter", "judging", "solutions", "autograder", "kit", "handin",
    "numpy", "scipy", "matplotlib", "cv2", "skimage", "PIL", "plotly", "IPython", "ipywidgets",
}

_QUESTION = {q.id: q for q in QUESTIONS}
_LABEL = re.compile(r"(?:^|[^a-z0-9])q(\d+)(?:[._-]?(\d+))?(?![0-9])")


def _identifier(name: str) -> bool:
    return name.isidentifier() and not keyword.iskeyword(name)


def module_names(filename: str) -> list[str]:
    """The module names the ``.py`` file ``filename`` (its path inside the hand-in) is importable by.

    Its stem (``andrew_hw4/code/submission.py`` -> ``submission``: the student ran their scripts
    from the file's folder), then every longer folder-relative dotted name whose parts are
    identifiers (``code.submission``, ``andrew_hw4.code.submission``); ``pkg/__init__.py`` is the
    package ``pkg``.  Names of the standard library and of the sandbox's packages are left out
    (those modules stay the real ones).  Empty for a file no import statement can name
    (``HW4 final.py``).
    """
    parts = list(PurePosixPath(filename).with_suffix("").parts)
    if parts and parts[-1] == "__init__":
        parts = parts[:-1]
    names = []
    for k in range(len(parts) - 1, -1, -1):
        tail = parts[k:]
        if not all(_identifier(p) for p in tail):
            break
        if tail[0] in _RESERVED:
            continue
        names.append(".".join(tail))
    return names


def private_module_name(filename: str, taken: Iterable[str]) -> str:
    """A module name of the grader's own for a file (``_hw4_file_q3_metric``), unique among ``taken``."""
    stem = re.sub(r"\W+", "_", PurePosixPath(filename).stem).strip("_") or "file"
    base = f"_hw4_file_{stem}"
    name, k, taken = base, 2, set(taken)
    while name in taken:
        name, k = f"{base}_{k}", k + 1
    return name


def file_label(filename: str) -> tuple[int, int | None] | None:
    """The question a file's name gives: ``q3_1_essential_matrix.py`` -> (3, 1), ``Q2 eightpoint.ipynb``
    -> (2, None), ``submission.py`` -> None."""
    m = _LABEL.search(PurePosixPath(filename).name.lower())
    if m is None:
        return None
    return int(m.group(1)), (int(m.group(2)) if m.group(2) else None)


def _squash(text: str) -> str:
    return re.sub(r"[^a-z0-9]", "", text.lower())


def file_rank(function: str, qid: str, filename: str, stem: str | None) -> tuple[int, str]:
    """How well a file matches a homework function's question: (rank, reason); lower is better.

    0: the file's name names the question (``q3_1_...`` for Q3.1, ``q2_...`` for Q2) or the
    function (``essential_matrix`` for essentialMatrix); 1: the file is the notebook of the
    question (by the number in its name or the stem in its metadata); 2: nothing matches.
    """
    q = _QUESTION[qid]
    number, _, sub = qid[1:].partition(".")
    label = file_label(filename)
    name = PurePosixPath(filename).name
    if label is not None and label[0] == int(number) and (label[1] == (int(sub) if sub else None)
                                                           or (not sub and label[1] is not None)):
        return 0, f"its file name {name} names {qid}"
    if _squash(function) in _squash(PurePosixPath(filename).stem):
        return 0, f"its file name {name} names {function}"
    if stem == q.notebook:
        return 1, f"{name} is the notebook of {qid} ({q.notebook})"
    return 2, ""


@dataclass(frozen=True)
class Candidate:
    """One file's definition of a homework function.

    filename: the file; stem: the manifest notebook the file answers (by name or metadata), or
    None; origin: where the winning definition inside that file is ("submission.py, line 12");
    order: the file's position in reading order; preference: a tie-break among files of one
    notebook (the kit's exact file name first); definitions: how many times the file defines it.
    """

    filename: str
    stem: str | None
    origin: str
    order: int
    preference: tuple = ()
    definitions: int = 1


def choose(function: str, qid: str, candidates: Sequence[Candidate]) -> tuple[Candidate, str]:
    """The definition of ``function`` (question ``qid``) that is used, and why, in words.

    The file matching the question best (:func:`file_rank`); among equally good files of one
    notebook, the kit's own file name first (an exact ``q2_eightpoint.ipynb`` over ``Copy of
    ...``); otherwise the last one in reading order (as if the files ran one after another).
    """
    if not candidates:
        raise ValueError(f"candidates: expected at least one definition of {function}, got none")
    def key(c: Candidate) -> tuple:
        rank = file_rank(function, qid, c.filename, c.stem)[0]
        return (rank, c.preference if rank < 2 else (), -c.order)

    ranked = sorted(candidates, key=key)
    best = ranked[0]
    rank, why = file_rank(function, qid, best.filename, best.stem)
    if len(candidates) == 1:
        return best, "the only definition"
    if rank < 2:
        tied = [c for c in candidates if file_rank(function, qid, c.filename, c.stem)[0] == rank]
        if len(tied) > 1:
            why += "; of the files that match as well, its name is closest to the kit's and it comes last"
        return best, why
    return best, "no file's name matches its question, and it is the last one defined (files read in path order)"


def signature_of(node: ast.AST) -> Signature | None:
    """The Signature of a ``def`` or of ``name = lambda ...`` (None for anything else)."""
    if isinstance(node, ast.Assign | ast.AnnAssign) and isinstance(node.value, ast.Lambda):
        args = node.value.args
    elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
        args = node.args
    else:
        return None
    positional = tuple(a.arg for a in args.posonlyargs + args.args)
    return Signature(positional, len(args.defaults), args.vararg.arg if args.vararg else None,
                     tuple(a.arg for a in args.kwonlyargs), args.kwarg.arg if args.kwarg else None)


def free_globals(tree_nodes: Iterable[ast.stmt], bound: set[str]) -> set[str]:
    """Names the kept statements read that they never bind at top level (nor are builtins):
    what a file relies on finding elsewhere (``eightpoint`` in a q3 file exported from the kit's
    notebooks, which shared one namespace)."""
    used = set()
    for node in tree_nodes:
        for n in ast.walk(node):
            if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Load):
                used.add(n.id)
    return used - bound - set(dir(builtins))
