"""Build the homework notebooks from one source: the student version, the answer key, the nbgrader source.

Two inputs, each written once:

- ``solutions/*.py``: the reference functions.  Their signature and docstring (the shape
  contract) go to every version; their body only to the answer key (verbatim) and to the
  nbgrader source (between ``### BEGIN SOLUTION`` / ``### END SOLUTION``).
- ``notebooks/src/<stem>.md``: the text and the figure cells of each notebook, in the format
  below; ``notebooks/src/settings.json`` holds the course repository the notebooks point to.

Source format
-------------
Markdown, split into cells by a line ``+++`` and before every question heading.  A line
``+++ page`` splits too, and the markdown cell after it starts a new page in the PDF (a section
printed apart from the question above it, such as Q3.2's errors, which come after Q3.3); after a
line ``+++ plumbing`` it is the kit's plumbing (how to work on Colab), left out of the PDF.  A question
heading is written bare (``## Q3.2``); the builder completes it from ``core.manifest``
(``## Q3.2 Triangulation [10 points]``), so titles and points live in one place.  Fenced blocks
opened by these lines become special cells (any other fence stays markdown):

``` ```python [tag ...]``      a code cell, the same in every version (tags go to the cell
                               metadata; ``figure`` marks a cell whose output must be an image).
                               ``### BEGIN SOLUTION`` / ``### END SOLUTION`` lines inside work
                               as in nbgrader: the key drops the markers, the student version
                               gets the nbgrader stub instead of the region.
``` ```{colab}``               the "Open in Colab" link (left out of the PDF).
``` ```{setup}``               the first code cell: finds (locally) or fetches (Colab) the kit
                               (one line in the PDF).
``` ```{solution} name``       the stub / reference / nbgrader cell of function ``name``.
``` ```{check} name``          the self-check cell ``check_<name>(<name>)`` from
                               ``starter.checks.<module of name in solutions/>``.
``` ```{answer} Q1.1 [points=N]`` a written answer graded by hand: the block is the key's answer.
                               ``ungraded`` instead of ``points=N``: read from the PDF only, no
                               nbgrader points (the autograded cells keep the question's points).

In the nbgrader source a function's imports and module-level helpers go inside its region,
nested in the function, because nbgrader replaces a region by a stub that must still run; the
answer key keeps them at the top level, as in solutions/.

Points: each check and answer cell under a question heading is graded (nbgrader); explicit
``points=`` are kept and the rest of the question's points are shared by the others.

Order of the steps (each a small function in a module of this package): parse the source -> expand bare headings ->
turn blocks into cells for one version -> attach nbgrader metadata (nbgrader source only) ->
assemble and validate the notebook -> write it.

The modules, each importing only those above it: ``source`` (steps 1-2: the sources and the
reference functions), ``setup`` (the settings, the setup cell, the Colab link), ``cells``
(step 3: block kind -> cells of one version), ``build`` (step 4: assemble, write, check, the
command).  This package re-exports what other modules and the tests use.
"""

from __future__ import annotations

from .build import OUT_DIRS, VARIANTS, add_arguments, build_all, build_notebook, main, outdated, output_path, write_all
from .cells import (
    ANSWER_PLACEHOLDER,
    BEGIN,
    END,
    NBGRADER_STUB,
    clear_regions,
    solution_text,
)
from .setup import PLACEHOLDER_REPO, Settings, load_settings, settings_of
from .source import (
    KIT_ROOT,
    METHOD_SECTION,
    SOLUTIONS_DIR,
    SRC_DIR,
    Block,
    Extracted,
    SourceError,
    find_module,
    extract_function,
    parse_source,
)

# What other modules and the tests use (the three private names: tests only).
__all__ = [
    "ANSWER_PLACEHOLDER",
    "BEGIN",
    "END",
    "KIT_ROOT",
    "METHOD_SECTION",
    "NBGRADER_STUB",
    "OUT_DIRS",
    "PLACEHOLDER_REPO",
    "SOLUTIONS_DIR",
    "SRC_DIR",
    "VARIANTS",
    "Block",
    "Extracted",
    "Settings",
    "SourceError",
    "add_arguments",
    "build_all",
    "build_notebook",
    "extract_function",
    "load_settings",
    "main",
    "outdated",
    "output_path",
    "parse_source",
    "settings_of",
    "write_all",
    "clear_regions",
    "find_module",
    "solution_text",
]
