"""Imports go only downward: every import of the shipped packages, also those inside functions.

The layers, bottom to top (README, "Layers"): a module may import its own package and any lower
layer, never a higher one and never a sibling of its own layer.  Each edge is read from the
source with ``ast`` (no module is imported), relative imports resolved, so an import hidden in a
function body counts like any other.  A second test looks for circles between modules.
"""

from __future__ import annotations

import ast
import functools
import sys
from pathlib import Path

import pytest

from core.paths import KIT_ROOT

# (layer, package): one top-level package per row, each package whole (its subpackages too) at
# one layer (test_each_package_is_at_one_layer).  starter and its self-checks (starter.checks)
# are one layer above judging: the helpers judging needs (rodrigues, camera2) live in core.
LAYERS: tuple[tuple[int, str], ...] = (
    (0, "core"),
    (1, "scenes"),
    (2, "judging"),
    (3, "starter"),
    (4, "handin"),
    (5, "solutions"),
    (6, "kit"),
    (7, "autograder"),
)
PACKAGES = sorted({name.split(".")[0] for _, name in LAYERS})


def split_packages(layers) -> list[str]:
    """The top-level packages that ``layers`` puts at more than one layer, or that have a dotted row.

    A package split across layers (as ``starter`` and ``starter.checks`` once were, on either side
    of ``judging``) makes importing the lower half load the upper one's ``__init__``.
    """
    rows: dict[str, set[int]] = {}
    dotted = set()
    for layer, name in layers:
        top = name.split(".")[0]
        rows.setdefault(top, set()).add(layer)
        if "." in name:
            dotted.add(top)
    return sorted(top for top, at in rows.items() if len(at) > 1 or top in dotted)


def test_each_package_is_at_one_layer():
    assert split_packages(LAYERS) == [], f"packages split across layers: {split_packages(LAYERS)}"
    assert len(PACKAGES) == len(LAYERS)


@pytest.mark.parametrize("layers", [((2, "starter"), (4, "starter.checks"), (3, "judging")),
                                    ((2, "starter"), (2, "starter.checks")),
                                    ((2, "starter"), (3, "starter"))])
def test_a_split_package_is_seen(layers):
    assert split_packages(layers) == ["starter"]


def package_of(module: str) -> tuple[int, str] | None:
    """The (layer, package) a dotted module name belongs to: the longest matching package."""
    best = None
    for layer, name in LAYERS:
        if module == name or module.startswith(name + "."):
            if best is None or len(name) > len(best[1]):
                best = (layer, name)
    return best


def module_name(path: Path) -> str:
    parts = list(path.relative_to(KIT_ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported_from(path: Path, node: ast.ImportFrom) -> str:
    """The dotted module a ``from ... import`` in ``path`` reads from, a relative one resolved."""
    mod = module_name(path)
    package = mod.split(".") if path.name == "__init__.py" else mod.split(".")[:-1]
    if not node.level:
        return node.module or ""
    return ".".join(package[: len(package) - node.level + 1] + ([node.module] if node.module else []))


@functools.cache
def _parsed(path: Path, stamp: tuple[int, int]) -> ast.Module:
    return ast.parse(path.read_text(encoding="utf-8"), str(path))


def parsed(path: Path) -> ast.Module:
    """``path``'s syntax tree, read once per run while the file is unchanged (its stamp: mtime, size):
    the checks below read the same few hundred files three or four times."""
    stat = path.stat()
    return _parsed(path, (stat.st_mtime_ns, stat.st_size))


def imports_of(path: Path) -> list[tuple[int, str]]:
    """(line, imported dotted name) for every import in the file, relative ones resolved."""
    found = []
    for node in ast.walk(parsed(path)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            target = imported_from(path, node)
            # "from pkg import mod" may name a submodule: count the most specific name.
            found += [(node.lineno, f"{target}.{a.name}" if a.name != "*" else target) for a in node.names]
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
              and node.func.attr == "import_module" and node.args
              and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)):
            found.append((node.lineno, node.args[0].value))
    return found


def shipped_files() -> list[Path]:
    return sorted(p for pkg in PACKAGES if (KIT_ROOT / pkg).is_dir() for p in (KIT_ROOT / pkg).rglob("*.py")
                  if "__pycache__" not in p.parts)


def kit_edges() -> list[tuple[str, int, str, str]]:
    """(file, line, importing module, imported kit module) for every import between kit packages."""
    edges = []
    for path in shipped_files():
        src = module_name(path)
        for line, target in imports_of(path):
            if target.split(".")[0] in PACKAGES:
                edges.append((str(path.relative_to(KIT_ROOT)), line, src, target))
    return edges


def test_every_shipped_package_has_a_layer():
    tops = {p.parent.name for p in KIT_ROOT.glob("*/__init__.py")}
    assert tops - {"tests", "benchmarks"} <= set(PACKAGES), f"packages without a layer: {tops - set(PACKAGES)}"


def test_the_reader_sees_imports_inside_functions(tmp_path, monkeypatch):
    # The checker itself must not miss a hidden import, or the next test proves nothing.  The probe
    # is the one module of a kit laid out in tmp_path: the kit's own folders are left alone (another
    # test process may be copying scenes/ into a release meanwhile).
    probe = tmp_path / "scenes" / "_layer_probe_tmp.py"
    probe.parent.mkdir()
    probe.write_text("def f():\n    from starter import data\n    return data\n", encoding="utf-8")
    monkeypatch.setattr(sys.modules[__name__], "KIT_ROOT", tmp_path)
    assert shipped_files() == [probe]
    edges = kit_edges()
    assert ("scenes/_layer_probe_tmp.py", 2, "scenes._layer_probe_tmp", "starter.data") in edges
    assert violations(edges)


def violations(edges) -> list[str]:
    bad = []
    for file, line, src, target in edges:
        a, b = package_of(src), package_of(target)
        if a is None or b is None or a[1] == b[1]:
            continue
        if b[0] >= a[0]:
            bad.append(f"{file}:{line}: {src} (layer {a[0]}, {a[1]}) imports {target} (layer {b[0]}, {b[1]})")
    return bad


@pytest.fixture(scope="module")
def edges() -> list[tuple[str, int, str, str]]:
    """``kit_edges()`` of the kit, read once for the two tests that need them."""
    return kit_edges()


def test_imports_only_go_down(edges):
    bad = violations(edges)
    assert not bad, "imports that go up a layer or sideways:\n" + "\n".join(bad)


def _module_graph(edges) -> dict[str, set[str]]:
    modules = {module_name(p) for p in shipped_files()}
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for _, _, src, target in edges:
        # "from pkg import name" where name is not a module resolves to the package itself.
        while target and target not in modules:
            target = target.rpartition(".")[0]
        if target and target != src:
            graph[src].add(target)
    return graph


def circles_of(graph: dict[str, set[str]]) -> list[str]:
    """Every circle a depth-first walk of ``graph`` (node -> the nodes it imports) meets, as "a -> b -> a"."""
    state: dict[str, int] = {}
    stack: list[str] = []
    circles: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for n in sorted(graph.get(m, ())):
            if state.get(n) == 1:
                circles.append(" -> ".join(stack[stack.index(n):] + [n]))
            elif n not in state:
                visit(n)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)
    return circles


def test_no_circle_between_modules(edges):
    circles = circles_of(_module_graph(edges))
    assert not circles, "import circles:\n" + "\n".join(circles)


# autograder/'s folders by role, bottom to top (docs/architecture.md): a folder imports its own
# modules and lower rows only.  The root holds the command line alone.
AUTOGRADER_FOLDERS: tuple[tuple[int, str], ...] = (
    (0, "autograder.sandbox"), (0, "autograder.submission"),
    (1, "autograder.inputs"), (1, "autograder.feedback"),
    (2, "autograder.review"),
    (3, "autograder.grading"),
    (4, "autograder.hidden"),
    (5, "autograder.channels"),
    (6, "autograder.channels.gradescope"), (6, "autograder.channels.nbgrader"), (6, "autograder.channels.cluster"),
    (7, "autograder"),
)


def folder_of(module: str, packages: set[str]) -> str:
    """A package's ``__init__`` belongs to its own folder; a module to the folder it lies in."""
    return module if module in packages else module.rpartition(".")[0]


def folder_graph(graph: dict[str, set[str]], packages: set[str]) -> dict[str, set[str]]:
    """The folders' imports: a module's folder imports each folder it takes a module from."""
    out: dict[str, set[str]] = {}
    for src, targets in graph.items():
        for t in targets:
            a, b = folder_of(src, packages), folder_of(t, packages)
            if a != b:
                out.setdefault(a, set()).add(b)
    return out


def _packages() -> set[str]:
    return {module_name(p) for p in shipped_files() if p.name == "__init__.py"}


def test_autograders_folders_import_only_downward_and_never_in_a_circle(edges):
    """autograder/'s folders can be read one at a time: each imports only the rows below it, and no
    two import each other, straight or round.

    A parent's own modules count as the parent's: ``autograder/__main__.py`` importing a channel
    while a channel imported ``autograder/config.py`` was such a circle.
    """
    rank = dict((name, layer) for layer, name in AUTOGRADER_FOLDERS)
    folders = folder_graph(_module_graph(edges), _packages())
    assert {f for f in _packages() if f.startswith("autograder")} == set(rank), "a folder without a row"
    bad = [f"{a} ({rank[a]}) imports {b} ({rank[b]})" for a, targets in sorted(folders.items()) if a in rank
           for b in sorted(targets) if b in rank and rank[b] >= rank[a]]
    assert not bad, "autograder folders that import sideways or up:\n" + "\n".join(bad)
    circles = [c for c in circles_of(folders) if c.startswith("autograder")]
    assert not circles, "folders that import each other:\n" + "\n".join(circles)


def test_a_circle_between_folders_is_seen():
    graph = {"kit.a.x": {"kit.b.y"}, "kit.b.y": set(), "kit.b.z": {"kit.a"}, "kit.a": set(), "kit.c.w": {"kit.a.x"}}
    folders = folder_graph(graph, {"kit.a", "kit.b", "kit.c"})
    assert folders == {"kit.a": {"kit.b"}, "kit.b": {"kit.a"}, "kit.c": {"kit.a"}}
    assert circles_of(folders) == ["kit.a -> kit.b -> kit.a"]


@pytest.mark.parametrize("module, layer", [("core.geometry", 0), ("core.rotations", 0), ("judging.bundle", 2),
                                           ("starter.checks.fundamental", 3), ("starter.epipolar", 3),
                                           ("autograder.hidden.x", 7), ("autograder.inputs.config", 7)])
def test_package_of(module, layer):
    assert package_of(module)[0] == layer


def test_judging_and_core_load_neither_starter_nor_scipy():
    """Importing every module of core and judging loads no starter (a higher layer) and no scipy.

    core.rotations imports scipy inside its functions only; the judgments run in every hidden
    test and self-check, and the sandbox's children import core before any student code.
    """
    import subprocess
    import sys

    modules = sorted(module_name(p) for pkg in ("core", "judging") for p in (KIT_ROOT / pkg).rglob("*.py")
                     if "__pycache__" not in p.parts)
    code = ("import importlib, sys\n"
            f"for m in {modules!r}:\n    importlib.import_module(m)\n"
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'starter', 'scipy'}))\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=KIT_ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr


def private_imports(paths) -> list[str]:
    """``file:line: module imports name`` for every ``from X import _name`` in ``paths`` where X is
    another module (a module's private names are its own: a neighbour needing one needs a public
    name for it)."""
    bad = []
    for path in paths:
        mod = module_name(path)
        for node in ast.walk(parsed(path)):
            if not isinstance(node, ast.ImportFrom):
                continue
            target = imported_from(path, node)
            for a in node.names:
                if a.name.startswith("_") and not a.name.startswith("__") and target != mod:
                    bad.append(f"{path.relative_to(KIT_ROOT)}:{node.lineno}: {target} imports {a.name}")
    return bad


def test_no_private_name_is_imported_from_another_module():
    files = shipped_files() + sorted((KIT_ROOT / "benchmarks").glob("*.py"))
    bad = private_imports(files)
    assert not bad, "private names imported across modules:\n" + "\n".join(bad)


def test_the_private_import_reader_sees_relative_and_absolute_imports(tmp_path, monkeypatch):
    pkg = tmp_path / "scenes"
    pkg.mkdir()
    (pkg / "a.py").write_text("from .b import _hidden, shown\nfrom scenes.b import _other\nfrom . import __doc__\n")
    monkeypatch.setattr(sys.modules[__name__], "KIT_ROOT", tmp_path)
    assert private_imports([pkg / "a.py"]) == ["scenes/a.py:1: scenes.b imports _hidden",
                                               "scenes/a.py:2: scenes.b imports _other"]



def is_test_of(test_file: Path, module: str) -> bool:
    """True when ``test_file`` (tests/<folder>/test_<words>.py) is a test of ``module``: one of the module's
    own names (its package and module names under the top-level package) is among its words."""
    words = set(test_file.stem.split("_")[1:])
    return bool(words & set(module.split(".")[1:]))


def test_tests_import_private_names_only_from_the_module_they_test():
    tests = KIT_ROOT / "tests"
    files = sorted(p for p in tests.rglob("*.py") if "__pycache__" not in p.parts)
    bad = []
    for line in private_imports(files):
        where, _, what = line.partition(": ")
        module = what.split(" imports ")[0]
        path = KIT_ROOT / where.split(":")[0]
        if not (path.name.startswith("test_") and is_test_of(path, module)):
            bad.append(line)
    assert not bad, "tests importing another module's private names:\n" + "\n".join(bad)


def test_the_install_lists_exactly_the_kits_packages():
    """pyproject's package list is what `pip install` ships: a folder left out is missing from a
    non-editable install, and a name whose folder is gone fails the install itself."""
    import tomllib

    listed = set(tomllib.loads((KIT_ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    folders = _packages()
    assert listed == folders, {"listed, no folder": sorted(listed - folders), "folder, not listed": sorted(folders - listed)}
