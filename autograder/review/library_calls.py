"""Library calls that do what the homework asks students to write: a list for the staff to look at.

A submission's code (every .py file and notebook code cell, not only the homework functions) is
parsed, never run, and every use of a listed name is reported: a call (``cv2.findFundamentalMat(
pts1, pts2)``), a reference (``ransac(data, FundamentalMatrixTransform, ...)``) or an import that
is never used.  Names are resolved through the file's imports, aliases included: ``import cv2 as
cv; cv.triangulatePoints(...)``, ``from cv2 import findFundamentalMat as f; f(...)``, ``from
scipy.spatial.transform import Rotation as R; R.from_rotvec(r)`` and ``from cv2 import *``.  The
cells of a notebook share their imports, as they share a kernel.  A name that is not imported
stands for itself, so ``cv2.recoverPose`` is found even when the import is in another notebook.

The list is ``DEFAULT_LIBRARY_CALLS`` unless the instructor's grader config names its own
(``library_calls``: a list of dotted names, see ``autograder.inputs.config``).  A listed name covers
what is under it: ``scipy.spatial.transform.Rotation`` covers ``Rotation.from_rotvec``.

The kit's own code is looked at the same way, always (whatever the list): a use of the kit
beyond what a student is given (``GIVEN_KIT``: the handout's helpers, the loaders and drawing
helpers, the self-checks, the hand-in tools, and what the answer key itself imports) is reported
as a kit internal, ``from judging.bundle import ...`` or ``starter.checks.pictures...`` alike: the
self-checks and the figures ship with the kit, and none of their insides is the student's to call.
Only names reached through the file's imports count (a variable called ``scenes`` is no package).

What is found goes to the staff only (the grade run's summary.md, the class report): it is a
reason to read the code, never a score, and static (``getattr(cv2, "find" + ...)`` or
``importlib.import_module`` escape it).
"""

from __future__ import annotations

import ast
import fnmatch
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from core.paths import KIT_ROOT
from core.untrusted import visible

from autograder.inputs.config import library_names

from .reader import blank_magics, code_units

__all__ = ["GIVEN_KIT", "KIT_INTERNAL", "KIT_PACKAGES", "LibraryCall", "find_in_class",
           "find_in_sources", "find_library_calls", "kit_internal", "markdown_code"]

# The kit's top-level packages: a name under one of them is the kit's own.
KIT_PACKAGES = ("core", "scenes", "starter", "judging", "handin", "solutions", "autograder", "kit")
# What of the kit a student may import (docs/students.md): module -> the names of it given
# (patterns; None: all of it, submodules included; "starter" gives what its __all__ lists).  A key
# ending in ".*" stands for each module directly under it.  Anything else of KIT_PACKAGES is internal.
GIVEN_KIT: dict[str, tuple[str, ...] | None] = {
    "starter": None,            # replaced by starter/__init__.py's __all__ (read, not imported)
    **{f"starter.{m}": None for m in ("data", "epipolar", "figures", "interactive", "keypoints", "pose", "ransac",
                                      "rotations", "notebook_import", "slow_call", "refine_comparison")},
    "starter.checks": ("check_*",),             # the self-checks
    "starter.checks.*": ("check_*",),
    "core.rotations": ("rodrigues", "invRodrigues"),   # the handout's helpers where they are defined
    "core.pose": ("camera2",),
    "core.validate": None,                      # the input checks the answer key uses
    "core.geometry": ("project", "depths", "IDENTITY_POSE"),
    "scenes.cameras": ("intrinsics", "look_at", "project"),   # Q1's picture of fixating cameras
    "handin": None,                             # handing in: the PDF, the code zip, the browser
}
KIT_INTERNAL = "a kit internal, not one of the helpers a student is given"

_SHOWN = 160  # characters of a use's code kept in the report


@dataclass(frozen=True)
class LibraryCall:
    """One use of a listed library name in a submission.

    name: the listed name it resolves to ("cv2.findFundamentalMat"); replaces: what of the
    homework that name does ("" for a name the default list does not describe); kind: "call",
    "reference" or "import"; code: the use as written (one line, shortened); where: the file or
    cell and line; function: the definition it is in ("" at top level).
    """

    name: str
    replaces: str
    kind: str
    code: str
    where: str
    function: str

    def as_dict(self) -> dict:
        return {"name": self.name, "replaces": self.replaces, "kind": self.kind, "code": self.code,
                "where": self.where, "function": self.function}


@lru_cache(maxsize=1)
def _starter_given() -> tuple[str, ...]:
    """starter/__init__.py's ``__all__``, read from its text (the review imports no student-facing code)."""
    tree = ast.parse((KIT_ROOT / "starter" / "__init__.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            return tuple(ast.literal_eval(node.value))
    return ()


def _given_names(module: str) -> tuple[str, ...] | None | bool:
    """The names ``module`` gives (None: all); False when it is no key of GIVEN_KIT."""
    if module == "starter":
        return _starter_given()
    if module in GIVEN_KIT:
        return GIVEN_KIT[module]
    parent = module.rpartition(".")[0]
    return GIVEN_KIT.get(f"{parent}.*", False) if parent else False


def kit_internal(qualified: str) -> bool:
    """Whether the dotted name ``qualified`` is of the kit (KIT_PACKAGES) and not given to students.

    A module on the way to a given name (``starter.checks``) is not internal: what is used of it is
    judged at the use.  ``module.*`` (a star import) is internal unless the module gives all it holds
    (``starter`` gives its ``__all__``, which a star import takes)."""
    parts = qualified.split(".")
    if parts[0] not in KIT_PACKAGES:
        return False
    if any(k == qualified or k.startswith(qualified + ".") for k in GIVEN_KIT) or _given_names(qualified) is not False:
        return False                                            # a module a given name lies in
    for k in range(len(parts) - 1, 0, -1):
        names = _given_names(".".join(parts[:k]))
        if names is False:
            continue
        if names is None or (parts[k] == "*" and k == 1 and parts[0] == "starter"):
            return False
        return not any(fnmatch.fnmatchcase(parts[k], pattern) for pattern in names)
    return True


def _listed(qualified: str, names: dict[str, str]) -> str | None:
    """The listed name that ``qualified`` is or is under, else None."""
    parts = qualified.split(".")
    for k in range(len(parts), 0, -1):
        head = ".".join(parts[:k])
        if head in names:
            return head
    return None


class _Aliases:
    """What the imports of one file (all cells of a notebook) bind: local name -> qualified name."""

    def __init__(self, parsed: Sequence[tuple[str, str, ast.AST]]):
        self.bound: dict[str, str] = {}
        self.star: list[str] = []
        self.star_imports: list[tuple[str, ast.stmt, int]] = []  # (module, statement, source)
        self.imports: list[tuple[str, str, ast.stmt, int]] = []  # (local name, qualified name, statement, source)
        for k, (_, text, tree) in enumerate(parsed):
            for node in ast.walk(tree):
                if isinstance(node, ast.Import):
                    for a in node.names:
                        local = a.asname or a.name.split(".")[0]
                        self.bound[local] = a.name if a.asname else local
                        self.imports.append((local, a.name, node, k))
                elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                    for a in node.names:
                        if a.name == "*":
                            self.star.append(node.module)
                            self.star_imports.append((node.module, node, k))
                            continue
                        self.bound[a.asname or a.name] = f"{node.module}.{a.name}"
                        self.imports.append((a.asname or a.name, f"{node.module}.{a.name}", node, k))

    def resolve(self, node: ast.AST, names: dict[str, str]) -> str | None:
        """The qualified name of a Name or Attribute chain, or None when it is not a plain chain."""
        attrs = []
        while isinstance(node, ast.Attribute):
            attrs.append(node.attr)
            node = node.value
        if not isinstance(node, ast.Name):
            return None
        head = self.bound.get(node.id)
        if head is None:
            starred = [f"{m}.{node.id}" for m in self.star if _listed(f"{m}.{node.id}", names)]
            head = starred[0] if starred else node.id
        return ".".join([head, *reversed(attrs)])

    def words(self, names: dict[str, str]) -> set[str]:
        """Every identifier through which code can reach a listed name: a text holding none of them
        holds no use, and is not visited."""
        out = {n.split(".")[0] for n in names}
        for local, qualified in self.bound.items():
            if _listed(qualified, names) or any(n.startswith(qualified + ".") for n in names):
                out.add(local)
        for module in self.star:
            out.update(n[len(module) + 1:].split(".")[0] for n in names if n.startswith(module + "."))
        out.update(local for local, qualified in self.bound.items() if qualified.split(".")[0] in KIT_PACKAGES)
        return out

    def kit_name(self, node: ast.AST) -> tuple[str, str] | None:
        """(local name, qualified name) of a Name or Attribute chain whose head an import binds to the
        kit (KIT_PACKAGES), else None."""
        attrs = []
        while isinstance(node, ast.Attribute):
            attrs.append(node.attr)
            node = node.value
        if not isinstance(node, ast.Name) or node.id not in self.bound:
            return None
        qualified = ".".join([self.bound[node.id], *reversed(attrs)])
        return (node.id, qualified) if qualified.split(".")[0] in KIT_PACKAGES else None


def _one_line(segment: str) -> str:
    text = " ".join(segment.split())
    return text if len(text) <= _SHOWN else text[:_SHOWN - 3] + "..."


class _Finder(ast.NodeVisitor):
    def __init__(self, aliases: _Aliases, names: dict[str, str], text: str, origin: str):
        self.aliases, self.names, self.text, self.origin = aliases, names, text, origin
        self.function: list[str] = []
        self.found: list[LibraryCall] = []
        self.used: set[str] = set()  # local names of imports that some use went through

    def _hit(self, target: ast.AST, shown: ast.AST, kind: str) -> bool:
        qualified = self.aliases.resolve(target, self.names)
        listed = _listed(qualified, self.names) if qualified else None
        if listed is None:
            return False
        root = target
        while isinstance(root, ast.Attribute):
            root = root.value
        self.used.add(root.id)
        code = ast.get_source_segment(self.text, shown) or ast.unparse(shown)
        self.found.append(LibraryCall(listed, self.names[listed], kind, _one_line(code),
                                      f"{self.origin}, line {shown.lineno}", ".".join(self.function)))
        return True

    def _kit(self, target: ast.AST, shown: ast.AST, kind: str) -> bool:
        """Whether ``target`` is a kit name reached through an import (judged whole: its parts are not
        visited); an internal one is recorded."""
        found = self.aliases.kit_name(target)
        if found is None:
            return False
        local, qualified = found
        self.used.add(local)
        if kit_internal(qualified):
            code = ast.get_source_segment(self.text, shown) or ast.unparse(shown)
            self.found.append(LibraryCall(qualified, KIT_INTERNAL, kind, _one_line(code),
                                          f"{self.origin}, line {shown.lineno}", ".".join(self.function)))
        return True

    def _scope(self, node) -> None:
        self.function.append(node.name)
        self.generic_visit(node)
        self.function.pop()

    visit_FunctionDef = visit_AsyncFunctionDef = visit_ClassDef = _scope

    def visit_Call(self, node: ast.Call) -> None:
        # the call as a whole is the use; its arguments may hold more (f(cv2.Rodrigues(r)))
        if not self._kit(node.func, node, "call") and not self._hit(node.func, node, "call"):
            self.visit(node.func)
        for child in [*node.args, *node.keywords]:
            self.visit(child)

    def visit_Attribute(self, node: ast.Attribute) -> None:
        if not self._kit(node, node, "reference") and not self._hit(node, node, "reference"):
            self.generic_visit(node)

    def visit_Name(self, node: ast.Name) -> None:
        if isinstance(node.ctx, ast.Load) and not self._kit(node, node, "reference"):
            self._hit(node, node, "reference")

    def visit_Import(self, node) -> None:  # imports are reported below, when unused
        return

    visit_ImportFrom = visit_Import


def find_in_sources(sources: Sequence[tuple[str, str]], names: dict[str, str] | None = None
                    ) -> tuple[list[LibraryCall], list[str]]:
    """(uses found, notes) in ``sources``: (origin, Python text) pairs sharing one namespace (the
    cells of one notebook, or one file).  A text that does not parse is a note, not an error."""
    names = library_names() if names is None else names
    # Every use goes through an import or a module named in full, so a text that never writes an
    # import, the first part of a listed name ("cv2", "scipy") or an alias of one holds none: it
    # is not parsed (most of the cells of a class; a cell that does not parse is then a note only
    # when it could hold a use).
    texts = [(origin, blank_magics(text)) for origin, text in sources]
    notes: list[str] = []

    def parse(chosen) -> list[tuple[str, str, ast.AST]]:
        out = []
        for origin, text in chosen:
            try:
                out.append((origin, text, ast.parse(text)))
            except (SyntaxError, ValueError) as exc:
                notes.append(f"{origin} does not parse: {getattr(exc, 'msg', exc)}")
        return out

    with_imports = parse([(o, t) for o, t in texts if "import" in t])
    aliases = _Aliases(with_imports)
    words = aliases.words(names)
    parsed = with_imports + parse([(o, t) for o, t in texts if "import" not in t and any(w in t for w in words)])
    found, used = [], set()
    for origin, text, tree in parsed:
        if not any(w in text for w in words):
            continue
        finder = _Finder(aliases, names, text, origin)
        finder.visit(tree)
        found += finder.found
        used |= finder.used
    for local, qualified, stmt, k in aliases.imports:
        listed = _listed(qualified, names)
        internal = kit_internal(qualified)
        if (listed or internal) and local not in used:
            origin, text, _ = parsed[k]
            found.append(LibraryCall(listed or qualified, names[listed] if listed else KIT_INTERNAL, "import",
                                     _one_line(ast.get_source_segment(text, stmt) or ast.unparse(stmt)),
                                     f"{origin}, line {stmt.lineno}", ""))
    for module, stmt, k in aliases.star_imports:
        if kit_internal(f"{module}.*"):
            origin, text, _ = parsed[k]
            found.append(LibraryCall(f"{module}.*", KIT_INTERNAL, "import",
                                     _one_line(ast.get_source_segment(text, stmt) or ast.unparse(stmt)),
                                     f"{origin}, line {stmt.lineno}", ""))
    return found, notes


def find_library_calls(path: str | Path, names: dict[str, str] | None = None) -> tuple[list[LibraryCall], list[str]]:
    """(uses found, notes) in the submission at ``path`` (folder, .zip, .ipynb or .py), file by file."""
    found, notes = [], []
    for _, sources in code_units(Path(path), notes):
        more, why = find_in_sources(sources, names)
        found += more
        notes += why
    return found, notes


def find_in_class(submissions: Iterable[tuple[str, str | Path]], names: dict[str, str] | None = None
                  ) -> dict[str, tuple[list[LibraryCall], list[str]]]:
    """student -> (uses found, notes) for each (student, submission path) of ``submissions``.

    A submission that is gone or unreadable gets a note, never an exception: the lists are
    written beside grades that must be written anyway.
    """
    out = {}
    for student, path in submissions:
        if str(path) in ("", "."):  # Path("") is the current folder: a record without a path, not a submission
            out[student] = ([], ["code not read (no submission path recorded)"])
            continue
        try:
            out[student] = find_library_calls(path, names)
        except Exception as exc:  # noqa: BLE001 - a deeply nested file can raise RecursionError in ast
            out[student] = ([], [f"code not read ({type(exc).__name__}: {exc})"])
    return out


def markdown_code(text: str) -> str:
    """``text`` as one Markdown code span, whatever backticks it holds (student text stays text:
    its controls made visible, on one line)."""
    text = visible(text).replace("\n", " ")
    run = max((len(m) for m in re.findall(r"`+", text)), default=0)
    fence = "`" * (run + 1)
    return f"{fence} {text} {fence}" if run else f"{fence}{text}{fence}"
