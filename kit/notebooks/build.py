"""Step 4 of the notebook build: assemble and validate one notebook in one version, build them all,
write them, check the committed ones, and the command ``python -m kit notebooks``."""

from __future__ import annotations

from pathlib import Path

import nbformat

from core.manifest import NOTEBOOKS, QUESTIONS, functions_of_notebook
from core.notebook import METADATA_KEY

from .cells import BuildState, block_to_cells, markdown_cell, share_points
from .setup import Settings, setup_text, load_settings
from .source import KIT_ROOT, SOLUTIONS_DIR, SRC_DIR, SourceError, parse_source

VARIANTS = ("student", "key", "nbgrader")
OUT_DIRS = {"student": Path("notebooks"), "key": Path("notebooks") / "key",
            "nbgrader": Path("notebooks") / "nbgrader" / "source" / "hw4"}


def build_notebook(stem: str, variant: str, settings: Settings | None = None, *,
                   src_dir: Path | None = None, solutions_dir: Path | None = None) -> nbformat.NotebookNode:
    """One notebook, in memory.

    Parameters
    ----------
    stem : a notebook of core.manifest ("q2_eightpoint").
    variant : "student", "key" or "nbgrader".
    settings : the course repository (default: notebooks/src/settings.json).
    src_dir, solutions_dir : where the sources and the reference functions are (tests use copies).

    Raises
    ------
    ValueError
        For an unknown stem or variant.
    SourceError
        When the source breaks a rule: a question of the notebook without heading, a function
        without solution cell, points that do not add up, a code cell before the setup cell...
    """
    if stem not in NOTEBOOKS:
        raise ValueError(f"stem: expected one of {list(NOTEBOOKS)}, got {stem!r}")
    if variant not in VARIANTS:
        raise ValueError(f"variant: expected one of {VARIANTS}, got {variant!r}")
    src_dir = Path(src_dir) if src_dir is not None else SRC_DIR
    settings = settings if settings is not None else load_settings(src_dir / "settings.json")
    path = src_dir / f"{stem}.md"
    if not path.exists():
        raise FileNotFoundError(f"stem: no source {path} for notebook {stem}")
    st = BuildState(stem, variant, settings, Path(solutions_dir) if solutions_dir is not None else SOLUTIONS_DIR)
    cells = []
    if variant == "key":
        cells.append(markdown_cell("**Answer key: for the course staff only. Do not share it with students.**"))
    for block in parse_source(path.read_text(encoding="utf-8"), path.name):
        cells += block_to_cells(block, st, f"{path.name}, line {block.line}")
    share_points(st, path.name)
    expected = [q.id for q in QUESTIONS if q.notebook == stem]
    if st.seen_questions != expected:
        raise SourceError(f"{path.name}: expected the question headings {expected} in this order, "
                          f"got {st.seen_questions}")
    if sorted(st.solutions) != sorted(functions_of_notebook(stem)):
        raise SourceError(f"{path.name}: expected solution cells for {list(functions_of_notebook(stem))}, "
                          f"got {st.solutions}")
    for k, cell in enumerate(cells):
        cell["id"] = f"{stem}-{k:02d}"
    nb = nbformat.v4.new_notebook(cells=cells)
    nb.metadata = {
        "kernelspec": {"display_name": "Python 3 (ipykernel)", "language": "python", "name": "python3"},
        "language_info": {"name": "python"},
        METADATA_KEY: {"stem": stem, "variant": variant, "repo_url": settings.repo_url, "ref": settings.ref},
    }
    nbformat.validate(nb)
    return nb


def output_path(stem: str, variant: str, root: Path | None = None) -> Path:
    """Where the built notebook goes, under ``root`` (default: the kit)."""
    return (Path(root) if root is not None else KIT_ROOT) / OUT_DIRS[variant] / f"{stem}.ipynb"


def build_all(settings: Settings | None = None, *, root: Path | None = None, src_dir: Path | None = None,
              solutions_dir: Path | None = None) -> dict[Path, nbformat.NotebookNode]:
    """Every notebook of every version, and the hand-in notebook: output path (under ``root``) -> notebook."""
    from handin.hand_in_notebook import HAND_IN_NAME, hand_in_notebook

    built = {output_path(stem, variant, root): build_notebook(stem, variant, settings, src_dir=src_dir,
                                                               solutions_dir=solutions_dir)
             for variant in VARIANTS for stem in NOTEBOOKS}
    hand_in = hand_in_notebook(setup_text(settings or load_settings()))
    for i, cell in enumerate(hand_in.cells):
        cell["id"] = f"hand-in-{i}"  # fixed, so that a rebuild is identical
    built[output_path(NOTEBOOKS[0], "student", root).parent / HAND_IN_NAME] = hand_in
    return built


def _dumps(nb: nbformat.NotebookNode) -> str:
    return nbformat.writes(nb) + "\n"


def write_all(settings: Settings | None = None, *, root: Path | None = None) -> list[Path]:
    """Build and write every notebook under ``root`` (default: the kit); returns the paths."""
    written = []
    for path, nb in build_all(settings, root=root).items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(_dumps(nb), encoding="utf-8")
        written.append(path)
    return written


def outdated(settings: Settings | None = None, *, root: Path | None = None) -> list[Path]:
    """The notebooks under ``root`` that differ from (or are missing from) a fresh build."""
    return [p for p, nb in build_all(settings, root=root).items()
            if not p.exists() or p.read_text(encoding="utf-8") != _dumps(nb)]


# ------------------------------------------------------------------------------------ CLI


def main(args) -> int:
    base = load_settings()
    settings = Settings(args.repo_url or base.repo_url, args.ref or base.ref)
    root = Path(args.out) if args.out else None
    if args.check:
        stale = outdated(settings, root=root)
        for p in stale:
            print(f"out of date: {p}")
        if not stale:
            print("every notebook matches its source")
        return 1 if stale else 0
    if root is not None:
        # A build outside the kit is made to be handed out: it must name the real repository.
        settings.require_repository("python -m kit notebooks --out")
    for p in write_all(settings, root=root):
        print(f"wrote {p}")
    if settings.is_placeholder:
        print("note: the kit's own notebooks keep the placeholder repository; students get notebooks from "
              "python -m kit release --repo-url https://github.com/ORG/REPO, which rebuilds them with it")
    return 0


def add_arguments(p) -> None:
    """The arguments of ``python -m kit notebooks``."""
    p.add_argument("--repo-url", default=None,
                   help="GitHub repository of the student release (https://github.com/ORG/REPO, or a local "
                        "file:///PATH), for the Colab links and the kit download (default: "
                        "notebooks/src/settings.json; its placeholder is refused with --out)")
    p.add_argument("--ref", default=None, help="branch or tag of that repository (default: settings.json, main)")
    p.add_argument("--out", default=None, help="write under this folder instead of the kit (notebooks/... inside)")
    p.add_argument("--check", action="store_true",
                   help="write nothing; exit 1 when a committed notebook differs from a fresh build")
