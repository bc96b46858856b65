"""The student release: what students download or clone, and nothing that gives an answer away.

``python -m kit release --out DIR`` writes

    core/ scenes/ starter/ judging/    the packages of ``core.shipping.STUDENT_PACKAGES`` (and judging/),
    handin/                            whole: helpers, public checks, scene generator, hand-in commands
    data/                              the data, without data/official/
    notebooks/<stem>.ipynb             the student notebooks and hand_in.ipynb, built for the release's
                                       repository (--repo-url; the committed ones are checked against
                                       their source first; the placeholder repository is refused)
    requirements.txt  pyproject.toml   so that ``pip install -r requirements.txt`` or ``pip install -e .`` works
    README.md                          a short guide for students

and never what ``core.shipping.NEVER_TO_STUDENTS`` lists (solutions/, autograder/, kit/, tests/,
benchmarks/, notebooks/key/, notebooks/nbgrader/, notebooks/src/, data/official/).  Before
returning it scans what it wrote (:func:`leaks`): a Python file or notebook that imports
``solutions`` or holds the body of a reference function, or a path that must never ship, stops
the release with an error naming the file.
"""

from __future__ import annotations

import ast
import shutil
from pathlib import Path

import nbformat

from core.manifest import NOTEBOOKS, QUESTIONS
from core.notebook import Cell, code_cells, parse_cells, read_text
from core.shipping import DATA_EXCLUDE, NEVER_TO_STUDENTS, STUDENT_OPTIONAL_PACKAGES, STUDENT_PACKAGES

__all__ = ["RELEASE_TOP", "leaks", "reference_bodies", "release_packages", "write_release"]

from core.paths import KIT_ROOT


def release_packages(kit_root: Path = KIT_ROOT) -> tuple[str, ...]:
    """The packages the release ships (``core.shipping``): the required ones and those optional ones present."""
    return STUDENT_PACKAGES + tuple(p for p in STUDENT_OPTIONAL_PACKAGES if (Path(kit_root) / p / "__init__.py").is_file())


# Everything the release may write at its top level (and all that --force may replace).
RELEASE_TOP = STUDENT_PACKAGES + STUDENT_OPTIONAL_PACKAGES + (
    "data", "notebooks", "requirements.txt", "pyproject.toml", "README.md", ".gitignore")
_SKIP_NAMES = {"__pycache__", ".ipynb_checkpoints", ".DS_Store", ".pytest_cache"}
_SKIP_SUFFIXES = {".pyc", ".pyo"}

_PYPROJECT = """\
[build-system]
requires = ["setuptools>=68"]
build-backend = "setuptools.build_meta"

[project]
name = "hw4-student-kit"
version = "{version}"
description = "Homework 4 (two-view 3D reconstruction): helpers, public checks, data and notebooks."
requires-python = ">=3.10"
dynamic = ["dependencies"]

[tool.setuptools]
packages = [{packages}]

[tool.setuptools.dynamic]
dependencies = {{ file = ["requirements.txt"] }}

[tool.setuptools.package-data]
handin = ["pdf_assets/*", "pdf_assets/*/*"]
"starter.checks" = ["*.json"]
"""

_GITIGNORE = "__pycache__/\n*.pyc\n.ipynb_checkpoints/\n*.egg-info/\nhw4.pdf\nhw4_code.zip\n"


def _readme(settings) -> str:
    order = "\n".join(f"{k}. `notebooks/{stem}.ipynb`: " + "; ".join(
        f"{q.id} {q.title} ({q.points} points{', extra credit' if q.extra_credit else ''})"
        for q in QUESTIONS if q.notebook == stem) for k, stem in enumerate(NOTEBOOKS, start=1))
    first = settings.colab_url(NOTEBOOKS[0])
    open_first = (f"Open the first notebook in Colab: {first} (every notebook has its \"Open in Colab\" "
                  "link at the top)" if first else
                  f"Upload a notebook to Colab (File > Upload notebook); its setup cell fetches the kit from "
                  f"{settings.repo_url}")
    return f"""\
# Homework 4: two-view 3D reconstruction

One notebook per problem, to do in order (later notebooks reuse your functions from earlier ones):

{order}

## On Google Colab (your work kept in Google Drive)

1. {open_first}.
2. Before typing anything, *File > Save a copy in Drive*. Colab keeps the copy in
   MyDrive/Colab Notebooks as "Copy of {NOTEBOOKS[0]}.ipynb": keep or change the name, the kit
   recognises its notebooks by their content. (Keeping them in MyDrive/hw4 works too.)
3. Write your name in `STUDENT_NAME` and run the setup cell (the first code cell). It mounts your
   Google Drive (allow access), downloads this kit once into MyDrive/hw4/kit and installs what
   Colab lacks. Run it first in every new session; later sessions find everything in Drive.
4. Do the same for each notebook, in order. Later notebooks load your functions from your saved
   earlier notebooks in Drive (a line says which file), so nothing is uploaded, in any session.
5. To hand in, open `notebooks/hand_in.ipynb` the same way and run it: it finds your notebooks
   in Drive (the most recently saved one per problem) and writes `hw4.pdf` and `hw4_code.zip` to
   MyDrive/hw4, and downloads them.

Colab without Drive: set `USE_DRIVE = False` in the setup cell. Nothing is kept when the session
ends, so upload your earlier notebooks (Files panel, into /content) before running a later one.

## On your own machine, or any Jupyter (no Google account needed)

Download this repository as a zip (on GitHub: Code > Download ZIP), unzip it, and in the
unzipped folder (Python 3.10 or later; a virtual environment is a good idea):

```
pip install -r requirements.txt jupyterlab
jupyter lab notebooks/
```

Open the notebooks from `notebooks/` and keep the six together there: each setup cell finds the
kit around its notebook, and later notebooks load your functions from their neighbours.

## What is here

- `starter/`: the helpers the homework gives you (`refineF`, `camera2`, `ransacF`, `rodrigues`,
  `invRodrigues`, data loading, figures) and the public self-checks the notebooks call.
- `data/`: the temple pair (`data/temple/`) and the car sequence (`data/q6/`). Set the environment
  variable `HW4_DATA` to use another folder with the same layout.
- `scenes/`: the generator that made this data.
- `handin/`: the hand-in commands below (the PDF for Gradescope, the code zip).

The self-checks are a help, not the grade: passing them promises nothing about the hidden tests.

## Handing in

Write your name in `STUDENT_NAME` in the first cell, run every notebook top to bottom and save.
On Colab run `notebooks/hand_in.ipynb` (above). On your own machine run it too, or:

```
python -m handin pdf notebooks/ --out hw4.pdf --code-zip hw4_code.zip
```

Submit `hw4.pdf` (mark the pages of each question on Gradescope) and `hw4_code.zip`.
"""


def _copy_tree(src: Path, dst: Path, exclude_top: set[str] = frozenset()) -> None:
    def ignore(folder, names):
        skip = {n for n in names if n in _SKIP_NAMES or Path(n).suffix in _SKIP_SUFFIXES}
        if Path(folder) == src:
            skip |= {n for n in names if n in exclude_top}
        return skip

    shutil.copytree(src, dst, ignore=ignore)


def reference_bodies(solutions_dir: Path | None = None) -> dict[str, str]:
    """``module.function`` -> ast dump of its body without the docstring, for every function of solutions/."""
    solutions_dir = Path(solutions_dir) if solutions_dir is not None else KIT_ROOT / "solutions"
    out = {}
    for path in sorted(solutions_dir.glob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                body = node.body
                if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                        and isinstance(body[0].value.value, str):
                    body = body[1:]
                if body:
                    out[f"{path.stem}.{node.name}"] = _dump_body(body)
    return out


def _dump_body(stmts) -> str:
    return "\n".join(ast.dump(s) for s in stmts)


def leaks(folder, solutions_dir: Path | None = None) -> list[str]:
    """Problems with the files under ``folder``: imports of ``solutions`` and reference bodies.

    Every ``.py`` file and every notebook's code cells are parsed; a function whose body is
    the body of a reference function (same ast) is reported, as is any ``import solutions``,
    ``from solutions...`` or a call such as ``importlib.import_module("solutions...")``.  A file that does
    not parse is reported too, since it could not be checked.
    """
    bodies = {dump: name for name, dump in reference_bodies(solutions_dir).items()}
    problems = []
    for path in sorted(Path(folder).rglob("*")):
        if path.suffix not in (".py", ".ipynb") or not path.is_file():
            continue
        rel = path.relative_to(folder)
        notebook = path.suffix == ".ipynb"
        try:
            data = path.read_bytes()
            parsed, bad = parse_cells(code_cells(data) if notebook else [Cell(1, read_text(data))])
        except (OSError, ValueError) as exc:  # an unreadable file is reported, not fatal
            problems.append(f"{rel}: not readable ({exc})")
            continue
        problems += [f"{rel}" + (f", cell {p.cell}" if notebook else "")
                     + f": does not parse ({p.message}), so it could not be checked" for p in bad]
        for pc in parsed:
            where = f"{rel}" + (f", cell {pc.cell.number}" if notebook else "")
            for node in ast.walk(pc.tree):
                if isinstance(node, ast.Import) and any(a.name.split(".")[0] == "solutions" for a in node.names):
                    problems.append(f"{where}: imports solutions")
                elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "solutions" \
                        and node.level == 0:
                    problems.append(f"{where}: imports from solutions")
                elif isinstance(node, ast.Call) and any(
                        isinstance(a, ast.Constant) and isinstance(a.value, str) and a.value.split(".")[0] == "solutions"
                        and a.value.replace(".", "").isidentifier() for a in node.args):
                    # importlib.import_module("solutions.pose"), __import__("solutions"): a plain
                    # string elsewhere (core.shipping's table) imports nothing.
                    problems.append(f"{where}: imports a solutions module by name")
                elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    body = node.body[1:] if (node.body and isinstance(node.body[0], ast.Expr)
                                             and isinstance(node.body[0].value, ast.Constant)) else node.body
                    hit = bodies.get(_dump_body(body))
                    if hit:
                        problems.append(f"{where}: {node.name} has the body of the reference {hit}")
    return problems


def _student_notebooks(notebooks_dir: Path, settings) -> dict[str, str]:
    """File name -> text of the release's notebooks: the student notebooks and the hand-in notebook,
    built for ``settings``.  Each committed student notebook is first checked against a fresh build
    with its own settings, so that a release never ships notebooks older than their source."""
    from handin.hand_in_notebook import HAND_IN_NAME
    from kit.notebooks import build_all, build_notebook, output_path, settings_of

    for stem in NOTEBOOKS:
        path = notebooks_dir / f"{stem}.ipynb"
        if not path.exists():
            raise FileNotFoundError(f"missing {path}: build the notebooks first (python -m kit notebooks)")
        nb = nbformat.read(path, as_version=4)
        variant = nb.metadata.get("hw4_kit", {}).get("variant")
        if variant != "student":
            raise ValueError(f"{path}: expected a student notebook, its metadata says {variant!r}")
        fresh = build_notebook(stem, "student", settings_of(nb))
        if nbformat.writes(fresh) != nbformat.writes(nb):
            raise ValueError(f"{path} differs from its source: rebuild it (python -m kit notebooks)")
    built = build_all(settings, root=Path("/release"))
    wanted = {output_path(stem, "student", Path("/release")) for stem in NOTEBOOKS}
    wanted.add(output_path(NOTEBOOKS[0], "student", Path("/release")).parent / HAND_IN_NAME)
    return {p.name: nbformat.writes(nb) + "\n" for p, nb in built.items() if p in wanted}


def _version() -> str:
    import re

    text = (KIT_ROOT / "pyproject.toml").read_text(encoding="utf-8")
    m = re.search(r'^version\s*=\s*"([^"]+)"', text, flags=re.MULTILINE)
    return m.group(1) if m else "0.0.0"


def write_release(out, *, data=None, force: bool = False, settings=None) -> list[Path]:
    """Write the student release into ``out``; return the files written.

    Parameters
    ----------
    out : str or Path
        Target folder.  It must be outside the kit, and empty or absent unless ``force``.
    data : str or Path, optional
        Data folder to ship (official layout: temple/, q6/); default: the kit's data/.
    force : bool
        Replace the release's own top-level entries (:data:`RELEASE_TOP`) in a non-empty ``out``;
        other files there are left alone.
    settings : kit.notebooks.Settings, optional
        The repository students get the kit from (default: notebooks/src/settings.json); the
        notebooks' Colab links, setup cells and the README point there.  The placeholder is refused.

    Raises
    ------
    ValueError
        When the repository is the placeholder (the message says what to pass), ``out`` is
        inside the kit (or holds it), is not empty without ``force``, when a committed student
        notebook is out of date, or when the written files leak an answer (the message lists
        them; the release is then removed).
    FileNotFoundError
        When the data folder or a student notebook is missing.
    """
    from kit.notebooks import load_settings

    settings = (settings if settings is not None else load_settings()).require_repository("python -m kit release")
    out = Path(out).resolve()
    kit = KIT_ROOT.resolve()
    if out == kit or kit in out.parents or out in kit.parents:
        raise ValueError(f"out: expected a folder outside the kit ({kit}), got {out}")
    if out.exists() and not out.is_dir():
        raise ValueError(f"out: expected a folder, got the file {out}")
    if out.exists() and any(out.iterdir()):
        if not force:
            raise ValueError(f"out: expected an empty or new folder, {out} holds files (use --force to replace "
                             f"the release's own entries: {', '.join(RELEASE_TOP)})")
        for name in RELEASE_TOP:
            target = out / name
            if target.is_dir():
                shutil.rmtree(target)
            elif target.exists():
                target.unlink()
    data = Path(data) if data is not None else kit / "data"
    if not (data / "temple").is_dir():
        raise FileNotFoundError(f"data: expected the homework data in {data} (temple/, q6/); "
                                "write it with python -m kit data")
    notebooks = _student_notebooks(kit / "notebooks", settings)

    out.mkdir(parents=True, exist_ok=True)
    packages = release_packages(kit)
    for name in packages:
        _copy_tree(kit / name, out / name)
    _copy_tree(data, out / "data", exclude_top=set(DATA_EXCLUDE))
    (out / "notebooks").mkdir()
    for name, text in notebooks.items():
        (out / "notebooks" / name).write_text(text, encoding="utf-8")
    shutil.copy2(kit / "requirements.txt", out / "requirements.txt")
    include = ", ".join(f'"{".".join(d.relative_to(out).parts)}"' for name in packages
                        for d in sorted([out / name, *(out / name).rglob("*")]) if (d / "__init__.py").is_file())
    (out / "pyproject.toml").write_text(_PYPROJECT.format(version=_version(), packages=include), encoding="utf-8")
    (out / "README.md").write_text(_readme(settings), encoding="utf-8")
    (out / ".gitignore").write_text(_GITIGNORE, encoding="utf-8")

    problems = leaks(out) + [f"{rel}: must never ship to students" for rel in NEVER_TO_STUDENTS
                             if (out / rel).exists()]
    if problems:
        for name in RELEASE_TOP:
            target = out / name
            if target.is_dir():
                shutil.rmtree(target)
            elif target.exists():
                target.unlink()
        raise ValueError("the release would give answers away, so it was removed:\n  " + "\n  ".join(problems))
    return sorted(p for p in out.rglob("*") if p.is_file())


def main(args) -> int:
    from kit.notebooks import Settings, load_settings

    base = load_settings()
    settings = Settings(args.repo_url or base.repo_url, args.ref or base.ref)
    files = write_release(args.out, data=args.data, force=args.force, settings=settings)
    size = sum(p.stat().st_size for p in files) / 2**20
    print(f"wrote the student release to {Path(args.out).resolve()}: {len(files)} files, {size:.1f} MB")
    print("contents: " + ", ".join(sorted({p.relative_to(Path(args.out).resolve()).parts[0] for p in files})))
    return 0


def add_arguments(p) -> None:
    """The arguments of ``python -m kit release``."""
    p.add_argument("--out", required=True, help="folder to write (outside the kit; new or empty)")
    p.add_argument("--data", default=None, help="data folder to ship (default: the kit's data/)")
    p.add_argument("--force", action="store_true", help="replace a previous release in --out")
    p.add_argument("--repo-url", default=None,
                   help="the repository students get the kit from: https://github.com/ORG/REPO, where you push "
                        "this release (or a local file:///PATH); default: notebooks/src/settings.json, whose "
                        "placeholder is refused")
    p.add_argument("--ref", default=None, help="branch or tag of that repository (default: settings.json, main)")
