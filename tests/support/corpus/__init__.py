"""The autograder's corpus: submissions built from the answer key (or the untouched student
notebooks) by one mutation each, every one named after the outcome it must get.

``CASES`` maps each name to a :class:`Case`: how to build it and what the grader must make of
it (which questions lose points, which mistake the feedback names, whether everything is zero).
``build(name, folder, out=...)`` writes the submission (a folder of notebooks) and returns its
path.  The notebooks come from ``kit.notebooks.build_notebook`` (the same build that writes
notebooks/key and the student notebooks), so the corpus follows the reference solutions.
"""

from __future__ import annotations

import copy
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import nbformat

from core.manifest import NOTEBOOKS
from core.paths import KIT_ROOT

from . import hostile, variants

__all__ = ["CASES", "IN_PROCESS", "KIT_ROOT", "Case", "build", "notebooks", "program_namespace", "trap_path"]

ALL_AUTOGRADED = frozenset({"Q2", "Q3.1", "Q3.2", "Q3.3", "Q4.1", "Q4.2", "Q5", "Q6"})

Notebooks = dict  # stem -> NotebookNode


@dataclass(frozen=True)
class Case:
    """A corpus submission and its expected grade.

    mutate : changes a copy of the base notebooks in place (the context gives ``kit``, ``out``
        and ``name`` for the hostile ones); base : "key" or "student";
    loses : questions that must score below full marks (all others full), or
    zero : every question must score 0 (then ``loses`` is ignored);
    mistakes : question -> name of the catalogue mistake its feedback must state;
    post : a last step on the written folder (to break a file).
    """

    mutate: Callable[[Notebooks, dict], None] = lambda nbs, ctx: None
    base: str = "key"
    loses: frozenset = frozenset()
    zero: bool = False
    mistakes: dict = field(default_factory=dict)
    post: Callable[[Path], None] | None = None


@lru_cache(maxsize=2)
def _built(variant: str) -> tuple:
    from kit.notebooks import build_notebook

    return tuple((stem, build_notebook(stem, variant)) for stem in NOTEBOOKS)


def notebooks(variant: str) -> Notebooks:
    """Fresh copies of the answer key ("key") or the student notebooks ("student")."""
    return {stem: copy.deepcopy(nb) for stem, nb in _built(variant)}


def stem_of(nbs: Notebooks, function: str) -> str:
    for stem, nb in nbs.items():
        if cell_index(nb, function) is not None:
            return stem
    raise LookupError(f"function: no notebook defines {function}")


def cell_index(nb, function: str) -> int | None:
    pattern = re.compile(rf"^def {re.escape(function)}\(", re.MULTILINE)
    for k, cell in enumerate(nb.cells):
        if cell.cell_type == "code" and pattern.search(cell.source):
            return k
    return None


def replace_function(nbs: Notebooks, function: str, source: str) -> None:
    """Put ``source`` in place of the cell that defines ``function``."""
    nb = nbs[stem_of(nbs, function)]
    nb.cells[cell_index(nb, function)] = nbformat.v4.new_code_cell(source)


def after_function(nbs: Notebooks, function: str, source: str) -> None:
    """Insert a cell with ``source`` right after the cell that defines ``function``."""
    nb = nbs[stem_of(nbs, function)]
    nb.cells.insert(cell_index(nb, function) + 1, nbformat.v4.new_code_cell(source))


def append_cell(nbs: Notebooks, stem: str, source: str) -> None:
    nbs[stem].cells.append(nbformat.v4.new_code_cell(source))


def delete_function(nbs: Notebooks, function: str) -> None:
    nb = nbs[stem_of(nbs, function)]
    del nb.cells[cell_index(nb, function)]


def syntax_error_in(nbs: Notebooks, function: str) -> None:
    """A stray unclosed bracket at the end of the cell that defines ``function``."""
    nb = nbs[stem_of(nbs, function)]
    cell = nb.cells[cell_index(nb, function)]
    cell.source += "\n\nprint('done'\n"


def duplicate_cells(nbs: Notebooks) -> None:
    for nb in nbs.values():
        nb.cells = nb.cells + [copy.deepcopy(c) for c in nb.cells]
        for k, c in enumerate(nb.cells):
            c["id"] = f"cell-{k}"


def _replace(function, source):
    return lambda nbs, ctx: replace_function(nbs, function, source)


def _after(function, source):
    return lambda nbs, ctx: after_function(nbs, function, source)


def _then(*steps):
    def run(nbs, ctx):
        for step in steps:
            step(nbs, ctx)
    return run


def _invalid_json(stem):
    def post(folder: Path):
        path = folder / f"{stem}.ipynb"
        path.write_text(path.read_text()[: len(path.read_text()) // 2])
    return post


CASES: dict[str, Case] = {
    # the two ends
    "key_full_marks": Case(),
    "untouched_student_zero": Case(base="student", zero=True),
    # common mistakes: each loses its own questions (and those that use the function) and is named
    "transposed_F_loses_Q2": Case(_replace("eightpoint", variants.EIGHTPOINT_TRANSPOSED),
                                  loses=frozenset({"Q2"}), mistakes={"Q2": "F transposed"}),
    "rank2_not_enforced_loses_part_of_Q2": Case(_replace("eightpoint", variants.EIGHTPOINT_RANK3),
                                                loses=frozenset({"Q2"}), mistakes={"Q2": "rank 2 not enforced"}),
    "F_not_unscaled_loses_Q2": Case(_replace("eightpoint", variants.EIGHTPOINT_NOT_UNSCALED),
                                    loses=frozenset({"Q2"}), mistakes={"Q2": "F not unscaled"}),
    "uint16_wraparound_loses_part_of_Q2": Case(_replace("eightpoint", variants.EIGHTPOINT_UINT16),
                                               loses=frozenset({"Q2"}), mistakes={"Q2": "uint16 wrap-around"}),
    "E_with_K1_K2_swapped_loses_Q3_1_and_Q3_3": Case(
        _replace("essentialMatrix", variants.ESSENTIAL_K_SWAPPED), loses=frozenset({"Q3.1", "Q3.3"}),
        mistakes={"Q3.1": "K1 and K2 swapped in E"}),
    "mean_instead_of_sum_error_loses_part_of_Q3_2": Case(
        _replace("triangulate", variants.TRIANGULATE_MEAN_ERROR), loses=frozenset({"Q3.2"}),
        mistakes={"Q3.2": "error not the sum of squares"}),
    "cheirality_sign_flipped_loses_Q3_3": Case(
        _replace("findM2", variants.FINDM2_CHEIRALITY_FLIPPED), loses=frozenset({"Q3.3"}),
        mistakes={"Q3.3": "wrong camera of the four"}),
    "x_and_y_swapped_matches_lose_Q4_1_and_Q4_2": Case(
        _after("epipolarCorrespondence", variants.WRAP_XY_SWAPPED), loses=frozenset({"Q4.1", "Q4.2"}),
        mistakes={"Q4.1": "x and y swapped"}),
    "interleaved_residuals_lose_part_of_Q5": Case(
        _after("rodriguesResidual", variants.WRAP_RESIDUAL_INTERLEAVED), loses=frozenset({"Q5"}),
        mistakes={"Q5": "residuals in another layout"}),
    "BA_returning_its_start_loses_part_of_Q5": Case(
        _replace("bundleAdjustment", variants.BA_RETURNS_START), loses=frozenset({"Q5"}),
        mistakes={"Q5": "BA error not decreasing"}),
    "threshold_inclusive_loses_part_of_Q6": Case(
        _after("MultiviewReconstruction", variants.WRAP_THRESHOLD_INCLUSIVE), loses=frozenset({"Q6"}),
        mistakes={"Q6": "detections at exactly Thres used"}),
    # valid alternatives
    "hartley_normalisation_full_marks": Case(_replace("eightpoint", variants.EIGHTPOINT_HARTLEY)),
    "no_refineF_full_marks": Case(_replace("eightpoint", variants.EIGHTPOINT_NO_REFINE)),
    "BA_with_minimize_full_marks": Case(_replace("bundleAdjustment", variants.BA_MINIMIZE)),
    "BA_with_plain_least_squares_full_marks": Case(_replace("bundleAdjustment", variants.BA_LEAST_SQUARES)),
    # broken notebooks
    "invalid_json_q2_loses_Q2": Case(post=_invalid_json("q2_eightpoint"), loses=frozenset({"Q2"})),
    "duplicated_cells_full_marks": Case(lambda nbs, ctx: duplicate_cells(nbs)),
    "missing_essentialMatrix_loses_Q3_1_and_Q3_3": Case(lambda nbs, ctx: delete_function(nbs, "essentialMatrix"),
                                                         loses=frozenset({"Q3.1", "Q3.3"})),
    "syntax_error_in_triangulate_cell_loses_Q3_2_Q3_3_Q4_2": Case(
        lambda nbs, ctx: syntax_error_in(nbs, "triangulate"), loses=frozenset({"Q3.2", "Q3.3", "Q4.2"})),
    # hostile: attacks on the grader earn nothing, and cost only the questions they sit in
    "patched_numpy_comparisons_zero": Case(
        lambda nbs, ctx: append_cell(nbs, "q2_eightpoint", hostile.PATCHED_NUMPY), base="student", zero=True),
    "always_true_objects_zero": Case(
        lambda nbs, ctx: append_cell(nbs, "q2_eightpoint", hostile.ALWAYS_TRUE_OBJECTS), base="student", zero=True),
    "sys_exit_and_os_exit_lose_Q2_Q3_1_Q3_3": Case(
        _then(_replace("eightpoint", hostile.EXIT_IN_EIGHTPOINT),
              _replace("essentialMatrix", hostile.OS_EXIT_IN_ESSENTIAL)),
        loses=frozenset({"Q2", "Q3.1", "Q3.3"})),
    "os_exit_while_loading_zero": Case(
        lambda nbs, ctx: append_cell(nbs, "q2_eightpoint", hostile.OS_EXIT_WHILE_LOADING), zero=True),
    # A cell after the key's, not in its place: that cell also holds the helper the key's
    # bundleAdjustment uses, so a replacement took bundle adjustment down too (all of Q5 lost).
    "infinite_loop_in_rodriguesResidual_loses_part_of_Q5": Case(
        _after("rodriguesResidual", hostile.INFINITE_LOOP), loses=frozenset({"Q5"})),
    "memory_bomb_in_eightpoint_loses_Q2": Case(_replace("eightpoint", hostile.MEMORY_BOMB), loses=frozenset({"Q2"})),
    "fork_bomb_in_findM2_loses_Q3_3": Case(_replace("findM2", hostile.FORK_BOMB), loses=frozenset({"Q3.3"})),
    "reads_grader_files_and_reference_zero": Case(
        lambda nbs, ctx: append_cell(nbs, "q2_eightpoint", hostile.reads_grader_files(ctx["kit"], ctx["out"])),
        base="student", zero=True),
    "writes_results_files_zero": Case(
        lambda nbs, ctx: append_cell(nbs, "q2_eightpoint", hostile.writes_results(ctx["out"], ctx["name"], ctx["trap"])),
        base="student", zero=True),
    "prints_fake_results_zero": Case(
        lambda nbs, ctx: append_cell(nbs, "q2_eightpoint", hostile.PRINTS_FAKE_RESULTS), base="student", zero=True),
    # one question's leaks must not cost the next: fds 1 and 2 sent to /dev/null through descriptors never
    # closed, another working folder, umask, environment, signal handler, warnings filter, stdout
    # replaced, on every call; before, the session ran out of descriptors ("Too many open files")
    # and the questions graded after that lost points they had earned
    "leaks_fds_and_cwd_in_epipolarCorrespondence_full_marks": Case(
        _after("epipolarCorrespondence", hostile.LEAKS_PROCESS_STATE)),
    "process_left_running_zero": Case(
        lambda nbs, ctx: append_cell(nbs, "q2_eightpoint", hostile.leaves_process(ctx["out"], ctx["name"])),
        base="student", zero=True),
}


def trap_path(out: str | Path) -> Path:
    """Where the hostile corpus tries to write results outside ``out`` (beside it, never created)."""
    return Path(out).resolve().parent / "gradescope-results" / "results.json"


def build(name: str, folder: str | Path, *, out: str | Path = "/nonexistent-grader-output") -> Path:
    """Write the corpus submission ``name`` as ``folder/name/<stem>.ipynb``; return that folder.

    ``out`` is the grader's output folder the hostile cases aim at.
    """
    case = CASES[name]
    nbs = notebooks(case.base)
    out = Path(out).resolve()
    case.mutate(nbs, {"kit": str(KIT_ROOT), "out": str(out), "name": name, "trap": str(trap_path(out))})
    target = Path(folder) / name
    target.mkdir(parents=True, exist_ok=True)
    for stem, nb in nbs.items():
        nbformat.write(nb, target / f"{stem}.ipynb")
    if case.post is not None:
        case.post(target)
    return target


def program_namespace(name: str, homework, case: Case | None = None) -> dict:
    """The namespace a corpus submission's kept statements make, executed here in the kit's tests.

    The statements are the ones the grader keeps (``core.notebook.definitions``), run in notebook
    order; one that fails costs nothing, as in the grader.  ``homework``: the function names that
    count as the homework's.  ``case``: a submission not in ``CASES`` (e.g. the key with one cell
    of variants.py in place), named ``name``.  Only the kit's own tests do this: the grader runs
    submissions in its sandbox, never in its own process.
    """
    from core.manifest import NOTEBOOKS
    from core.notebook import definitions, python_cells

    case = CASES[name] if case is None else case
    nbs = notebooks(case.base)
    case.mutate(nbs, {"kit": str(KIT_ROOT), "out": "/nonexistent", "name": name, "trap": "/nonexistent"})
    namespace: dict = {"__name__": f"corpus_{name}"}
    for stem in NOTEBOOKS:
        cells, _ = python_cells(dict(nbs[stem]))
        for d in definitions(cells, homework=homework):
            try:
                exec(compile(d.source, f"<{name}/{stem}>", "exec"), namespace)  # noqa: S102 - the kit's own corpus
            except Exception:  # noqa: BLE001 - a failing statement costs nothing, as in the grader
                pass
    return namespace


# What tests may run in their own process (tests/judging_tests/test_judgments_agree.py, tests/end_to_end/test_secret_sweep.py):
# not the hostile cases (exits, bombs, loops, grader files, leaked process state: the sandbox's
# business, and they would break the test process itself) nor those broken after writing (``post``:
# an unreadable file, the same under any secret).
_SANDBOX_ONLY = ("patched_numpy", "always_true", "exit", "infinite_loop", "bomb", "reads_grader", "writes_results",
                 "prints_fake", "process_left", "leaks_")
IN_PROCESS = tuple(n for n, c in CASES.items() if c.post is None and not any(h in n for h in _SANDBOX_ONLY))
