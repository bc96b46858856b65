"""The answer-key submission: the key notebooks, as a student would hand them in (a folder and a .zip)."""

from __future__ import annotations

import os
import shutil
import zipfile
from pathlib import Path

from core.manifest import NOTEBOOKS

__all__ = ["write_key_submission"]

KIT_ROOT = Path(__file__).resolve().parents[1]


def write_key_submission(out: str | os.PathLike, *, zip_it: bool = True) -> Path:
    """Write the answer-key submission to ``out/hw4_key/`` (and ``out/hw4_key.zip``); return it.

    The notebooks are copied from notebooks/key when all of them are there, else built from
    solutions/ with ``kit.notebooks`` (the same build that writes notebooks/key).
    """
    out = Path(out)
    folder = out / "hw4_key"
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    key_dir = KIT_ROOT / "notebooks" / "key"
    if all((key_dir / f"{stem}.ipynb").is_file() for stem in NOTEBOOKS):
        for stem in NOTEBOOKS:
            shutil.copy2(key_dir / f"{stem}.ipynb", folder / f"{stem}.ipynb")
    else:
        import nbformat

        from kit.notebooks import build_notebook

        for stem in NOTEBOOKS:
            nbformat.write(build_notebook(stem, "key"), folder / f"{stem}.ipynb")
    if not zip_it:
        return folder
    archive = out / "hw4_key.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as zf:
        for p in sorted(folder.glob("*.ipynb")):
            zf.write(p, p.name)
    return archive
