"""The kit's files a grading machine needs, as Gradescope's bundle and nbgrader's course ship them.

``grader_files``: the packages of ``core.shipping.GRADER_PACKAGES`` and requirements.txt;
``package_files``: one package's files; ``data_files``: data/ (or the default data generated when a
fresh checkout has none).  Caches, hidden files and compiled files never ship.
"""

from __future__ import annotations

from pathlib import Path

from core.paths import KIT_ROOT
from core.shipping import GRADER_PACKAGES

__all__ = ["data_files", "grader_files", "package_files"]

_SKIP_PARTS = {"__pycache__", ".ipynb_checkpoints", ".pytest_cache", ".mypy_cache", ".ruff_cache"}
_SKIP_SUFFIXES = (".pyc", ".pyo")


def _kept(path: Path, root: Path) -> bool:
    parts = path.relative_to(root).parts
    return not (any(p in _SKIP_PARTS or p.startswith(".") for p in parts) or path.name.endswith(_SKIP_SUFFIXES))


def package_files(root: Path, package: str) -> list[Path]:
    folder = root / package
    if not (folder / "__init__.py").is_file():
        raise FileNotFoundError(f"kit_root: expected the package {package}/ in {root}, found none")
    return sorted(p for p in folder.rglob("*") if p.is_file() and not p.is_symlink() and _kept(p, root))


def grader_files(kit_root: str | Path = KIT_ROOT) -> list[tuple[str, Path]]:
    """The kit's files a grading environment needs: ``(relative posix path, source file)``, sorted.

    The packages of ``core.shipping.GRADER_PACKAGES`` whole and ``requirements.txt``.  Data and
    configuration are not included (see ``build_bundle``).

    Raises
    ------
    FileNotFoundError
        When a package or requirements.txt is missing from ``kit_root``.
    """
    root = Path(kit_root).resolve()
    files = [p for pkg in GRADER_PACKAGES for p in package_files(root, pkg)]
    requirements = root / "requirements.txt"
    if not requirements.is_file():
        raise FileNotFoundError(f"kit_root: expected requirements.txt in {root}, found none")
    out = [(p.relative_to(root).as_posix(), p) for p in files + [requirements]]
    return sorted(set(out))


def data_files(kit_root: Path, scratch: Path) -> list[tuple[str, Path]]:
    """The kit's data/ files as ``(data/..., source file)``, or the default data generated into
    ``scratch/data`` when the kit's data/ has none (a fresh checkout before ``python -m kit data``)."""
    data = kit_root / "data"
    found = sorted(p for p in data.rglob("*") if p.is_file() and _kept(p, kit_root)) if data.is_dir() else []
    if not found:
        from scenes.defaults import write_default_data

        found = write_default_data(scratch / "data")
        data = scratch / "data"
    return [("data/" + p.relative_to(data).as_posix(), p) for p in found]
