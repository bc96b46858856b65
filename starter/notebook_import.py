"""Reuse your answers from an earlier notebook, and run unfinished work without crashing.

Problems 3 to 5 need functions written in earlier notebooks (``eightpoint`` in Q2, ``findM2`` and
``triangulate`` in Q3).  Rather than copying them, a later notebook loads them from its sibling:

>>> eightpoint = from_notebook("q2_eightpoint.ipynb", "eightpoint")          # doctest: +SKIP
>>> findM2, triangulate = from_notebook("q3_metric_reconstruction.ipynb",
...                                     "findM2", "triangulate")           # doctest: +SKIP

Only the definitions of that notebook run (:func:`core.notebook.definitions`, the rule set the
grader uses too): its top-level ``import`` statements, ``def`` and ``class`` blocks, ``try``
blocks of those, and ``name = from_notebook(...)`` lines (so chains work).  Constants, figures,
data loading and every other statement are skipped, so loading is quick and has no side effects.
The notebook is looked up beside the running one (the current folder), so the answer key's
notebooks load the answer key's siblings and yours load yours; a copy that Colab or a browser
renamed ("Copy of q2_eightpoint.ipynb") is found by the stem in its metadata.  On Colab the
setup cell also names the folders of Google Drive where your notebooks are kept (``$HW4_NOTEBOOKS``:
MyDrive/hw4 and MyDrive/Colab Notebooks); then the most recently saved notebook of that problem in
any of them is used, and a line says which file it was (:func:`locate_notebook`).

:func:`try_run` calls a function and turns ``NotImplementedError`` into a one-line note, so a
notebook whose stubs are not written yet still runs from top to bottom; any other exception
becomes a short message naming the function that failed, so a crash in one figure cell stops
that step only and the later cells still run (they see None and skip what needs it).
"""

from __future__ import annotations

import __future__
import ast
import builtins
import linecache
import os
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from core.manifest import NOTEBOOKS, QUESTIONS
from core.paths import KIT_ROOT
from core.notebook import NotebookUnreadable, definitions, find_notebook, notebook_stem, python_cells

__all__ = ["NOTEBOOKS_ENV", "from_notebook", "homework_notebooks", "locate_notebook", "notebook_definitions",
           "notebook_folders", "try_run"]

# Set by the notebooks' setup cell on Colab: the folders (os.pathsep-separated) that hold the
# student's notebooks, searched after the current folder.
NOTEBOOKS_ENV = "HW4_NOTEBOOKS"

# Notebooks being loaded right now, to report a cycle instead of recursing forever.
_LOADING: list[Path] = []


def notebook_folders(folder=None) -> list[Path]:
    """Where a homework notebook is looked for: ``folder`` (default: the current folder), then the
    folders of ``$HW4_NOTEBOOKS`` that exist (set by the setup cell on Colab; unset elsewhere)."""
    first = Path(folder) if folder is not None else Path.cwd()
    extra = [Path(f) for f in os.environ.get(NOTEBOOKS_ENV, "").split(os.pathsep) if f]
    out = [first]
    for f in extra:
        if f.is_dir() and f.resolve() not in {o.resolve() for o in out}:
            out.append(f)
    return out


def locate_notebook(stem: str, folder=None, *, search: bool = True) -> Path | None:
    """The notebook of problem ``stem`` ("q2_eightpoint"), or None.

    Without ``$HW4_NOTEBOOKS`` (or with ``search=False``): ``<stem>.ipynb`` in ``folder`` (default:
    the current folder), else a copy there whose metadata names ``stem``
    (:func:`core.notebook.find_notebook`).  With it (Colab): every notebook of that problem in
    :func:`notebook_folders`, whatever its name ("Copy of q2_eightpoint.ipynb", "... (1).ipynb"),
    and the most recently saved one wins, since Colab saves the notebook being worked on.
    """
    if stem not in NOTEBOOKS:
        raise ValueError(f"stem: expected one of {list(NOTEBOOKS)}, got {stem!r}")
    folders = notebook_folders(folder) if search else [Path(folder) if folder is not None else Path.cwd()]
    if len(folders) == 1:
        return find_notebook(folders[0], stem)
    found = []
    for f in folders:
        for path in f.glob("*.ipynb"):
            try:
                if path.is_file() and (path.stem == stem or notebook_stem(path.read_bytes()) == stem):
                    found.append(path)
            except OSError:
                continue
    return max(found, key=lambda p: (p.stat().st_mtime, p.name == f"{stem}.ipynb")) if found else None


def homework_notebooks(folder=None) -> dict[str, Path]:
    """Problem stem -> its notebook (:func:`locate_notebook`), for every problem found, in homework order."""
    return {stem: path for stem in NOTEBOOKS if (path := locate_notebook(stem, folder)) is not None}


def _resolve(notebook, folder) -> Path:
    if not isinstance(notebook, (str, os.PathLike)):
        raise ValueError(f"notebook: expected a file name such as 'q2_eightpoint.ipynb', got {notebook!r}")
    path = Path(notebook).expanduser()
    if path.suffix != ".ipynb":
        raise ValueError(f"notebook: expected a .ipynb file name, got {str(notebook)!r}")
    searched = [path.parent]
    if not path.is_absolute():
        search = folder is None
        if folder is None:
            # A from_notebook line inside a notebook being loaded means that notebook's folder.
            folder = _LOADING[-1].parent if _LOADING else Path.cwd()
        path = Path(folder) / path
        if path.stem in NOTEBOOKS and len(Path(notebook).parts) == 1:
            searched = notebook_folders(folder) if search else [Path(folder)]
            found = locate_notebook(path.stem, folder, search=search)
            if found is not None and found != path:
                print(f"{path.stem}: using {found}")
            path = found or path
    if not path.is_file() and path.stem in NOTEBOOKS:
        path = find_notebook(path.parent, path.stem) or path
    if not path.is_file():
        raise FileNotFoundError(
            f"notebook: {path.name} not found in {' or '.join(str(f) for f in searched)}. Keep your homework "
            f"notebooks in one folder. On Colab, run the setup cell (first code cell) and keep your notebooks "
            f"in Google Drive: File > Save a copy in Drive puts them in MyDrive/Colab Notebooks (MyDrive/hw4 "
            f"works too; names such as 'Copy of {path.name}' are fine). Or paste the function into a cell "
            f"of this notebook instead.")
    return path.resolve()


_HOMEWORK = frozenset(f for q in QUESTIONS for f in q.functions)


def notebook_definitions(notebook, folder=None) -> list[tuple[str, ast.stmt, str]]:
    """The statements :func:`from_notebook` would run, without running them.

    Parameters
    ----------
    notebook : str or Path
        A ``.ipynb`` file, relative to ``folder`` (default: the current folder).
    folder : str or Path, optional

    Returns
    -------
    list of (origin, statement, cell_source)
        ``origin`` is "<name>.ipynb, cell k" (k counts all cells from 1), ``statement`` the
        parsed top-level statement and ``cell_source`` the Python text of its cell.
    """
    path = _resolve(notebook, folder)
    try:
        parsed, problems = python_cells(path.read_bytes())
    except (NotebookUnreadable, OSError) as exc:
        raise ValueError(f"notebook: {path.name} is not a readable notebook ({exc})") from None
    for p in problems:
        warnings.warn(f"{path.name}, cell {p.cell}: {p.message} (line {p.line}); "
                      "its definitions are not loaded", stacklevel=3)
    return [(f"{path.name}, cell {d.cell.number}", d.node, d.cell_text)
            for d in definitions(parsed, constants=False, links=True, homework=_HOMEWORK)]


def from_notebook(notebook, *names: str, folder=None):
    """Load functions (or classes) defined in another notebook.

    Parameters
    ----------
    notebook : str or Path
        The notebook file, e.g. ``"q2_eightpoint.ipynb"``; a relative name is looked up in
        ``folder`` (default: the current folder, which in Jupyter and Colab is the folder of
        the running notebook).
    *names : str
        The names to return, at least one.
    folder : str or Path, optional
        Where to look instead of the current folder.

    Returns
    -------
    object or tuple
        The single object when one name is asked for, else a tuple in the order of ``names``.
        Each call reads the notebook again, so a saved change is picked up.

    Raises
    ------
    FileNotFoundError
        When the notebook is not there (the message says what to do on Colab).
    ImportError
        When the notebook does not define one of ``names`` (the message lists what it does
        define), or when notebooks load each other in a cycle.
    ValueError
        When no name is given or ``notebook`` is not a ``.ipynb`` file name.
    """
    if not names:
        raise ValueError("names: expected at least one name to load, e.g. from_notebook(nb, 'eightpoint'), got none")
    for n in names:
        if not isinstance(n, str) or not n.isidentifier():
            raise ValueError(f"names: expected Python identifiers, got {n!r}")
    path = _resolve(notebook, folder)
    if path in _LOADING:
        chain = " -> ".join(p.name for p in _LOADING + [path])
        raise ImportError(f"notebook: notebooks load each other in a cycle ({chain})")
    namespace: dict[str, Any] = {"__name__": f"notebook_{path.stem}", "__builtins__": builtins}
    _LOADING.append(path)
    flags = 0
    try:
        for origin, node, text in notebook_definitions(path):
            # Registered so that a traceback through the loaded code shows its lines.
            linecache.cache[origin] = (len(text), None, text.splitlines(True), origin)
            if isinstance(node, ast.ImportFrom) and node.module == "__future__":
                flags |= sum(getattr(__future__, a.name).compiler_flag for a in node.names
                             if hasattr(__future__, a.name))
            code = compile(ast.Module(body=[node], type_ignores=[]), origin, "exec", flags=flags,
                           dont_inherit=True)
            try:
                exec(code, namespace)  # noqa: S102 - the student's own definitions, in their own kernel
            except Exception as exc:
                if hasattr(exc, "add_note"):
                    exc.add_note(f"(while loading the definitions of {origin}, line {node.lineno})")
                raise
    finally:
        _LOADING.pop()
    missing = [n for n in names if n not in namespace]
    if missing:
        defined = sorted(k for k, v in namespace.items() if not k.startswith("__") and callable(v))
        raise ImportError(f"names: {path.name} defines no {', '.join(missing)} in a def/import cell "
                          f"(it defines: {', '.join(defined) or 'nothing'})")
    values = tuple(namespace[n] for n in names)
    return values[0] if len(values) == 1 else values


def _where_it_failed(tb) -> tuple[str | None, int | None]:
    """(function, line) of the innermost traceback frame outside the installed libraries and the
    kit's own packages: the student's code, when it is in the traceback at all."""
    import sysconfig

    folders = {Path(sysconfig.get_paths()[k]).resolve() for k in ("stdlib", "platstdlib", "purelib", "platlib")}
    folders |= {KIT_ROOT / package for package in ("core", "scenes", "starter", "judging", "handin")}
    prefixes = tuple(str(f) + os.sep for f in folders)
    found = (None, None)
    while tb is not None:
        name = tb.tb_frame.f_code.co_filename
        resolved = name if name.startswith("<") else str(Path(name).resolve())
        if not resolved.startswith(prefixes):
            found = (tb.tb_frame.f_code.co_name, tb.tb_lineno)
        tb = tb.tb_next
    return found


def try_run(fn: Callable, *args, **kwargs):
    """``fn(*args, **kwargs)``, or None with a short note when it could not finish.

    ``NotImplementedError`` (what the stubs raise) gives "<name>: not implemented yet, so this
    step is skipped."; the note names the function whose stub raised, which may be one called by
    ``fn`` (a check, or a function loaded from an earlier notebook).  Any other ``Exception``
    gives "<fn> failed: <Type>: <first line of the message>", with the function and line of your
    code where it was raised when that is another place, and the advice to call the function
    directly for the full traceback.  Either way the cell goes on and its caller gets None, so
    one crash does not turn every later cell into a NameError.  ``KeyboardInterrupt`` (the stop
    button) and ``SystemExit`` pass through.

    Examples
    --------
    >>> def stub(x):
    ...     raise NotImplementedError()
    >>> try_run(stub, 1) is None
    stub: not implemented yet, so this step is skipped.
    True
    >>> try_run(lambda: 1 / 0) is None
    <lambda> failed: ZeroDivisionError: division by zero. This step is skipped; call it directly to see the traceback.
    True
    """
    if not callable(fn):
        raise ValueError(f"fn: expected a function, got {type(fn).__name__}")
    caller = getattr(fn, "__name__", None) or "this step"
    try:
        return fn(*args, **kwargs)
    except NotImplementedError as exc:
        tb = exc.__traceback__
        while tb is not None and tb.tb_next is not None:
            tb = tb.tb_next
        culprit = tb.tb_frame.f_code.co_name if tb is not None else caller
        after = f" ({caller} skipped)" if caller != culprit else ""
        print(f"{culprit}: not implemented yet, so this step is skipped{after}.")
        return None
    except Exception as exc:  # noqa: BLE001 - contained on purpose: one failed step, not a failed notebook
        first = (str(exc).strip().splitlines() or [""])[0]
        if len(first) > 160:
            first = first[:157] + "..."
        what = f"{type(exc).__name__}: {first}" if first else type(exc).__name__
        function, line = _where_it_failed(exc.__traceback__)
        place = f" (raised in {function}, line {line})" if function and function != caller else ""
        print(f"{caller} failed: {what}{place}. This step is skipped; call it directly to see the traceback.")
        return None
