"""A submission whose every homework function hangs (a busy loop), for the time-limit tests and
benchmarks of the Gradescope channel.  Kept out of ``CASES``: grading it takes every check's
whole time limit, so the class-wide corpus tests do not run it.
"""

from __future__ import annotations

import re
from pathlib import Path

import nbformat

from core.manifest import QUESTIONS

from . import cell_index, stem_of, notebooks

__all__ = ["ALL_HANG", "build_all_hang", "hanging_functions"]

ALL_HANG = "every_function_hangs"


def hanging_functions() -> list[str]:
    """The manifest's autograded functions, in manifest order."""
    return [f for q in QUESTIONS if not q.by_hand for f in q.functions]


def build_all_hang(folder: str | Path) -> Path:
    """Write the answer key with every autograded function's cell replaced by the same signature
    and a ``while True: pass`` body, as ``folder/every_function_hangs/<stem>.ipynb``."""
    nbs = notebooks("key")
    for function in hanging_functions():
        nb = nbs[stem_of(nbs, function)]
        k = cell_index(nb, function)
        found = re.search(rf"^def {re.escape(function)}\((.*?)\):", nb.cells[k].source, re.MULTILINE | re.DOTALL)
        signature = found.group(1) if found else "*args, **kwargs"
        nb.cells[k] = nbformat.v4.new_code_cell(f"def {function}({signature}):\n    while True:\n        pass\n")
    target = Path(folder) / ALL_HANG
    target.mkdir(parents=True, exist_ok=True)
    for stem, nb in nbs.items():
        nbformat.write(nb, target / f"{stem}.ipynb")
    return target
