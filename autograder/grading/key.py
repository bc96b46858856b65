"""The answer-key submission: the key notebooks, as a student would hand them in (a folder and a .zip).

What it writes is readable by its owner only (folder 0700, files 0600): an answer key left in a
shared place such as /tmp must not be readable by the sandbox's uid, nor by anyone else.
"""

from __future__ import annotations

import os
import shutil
import zipfile
from pathlib import Path

from core.manifest import NOTEBOOKS
from core.paths import KIT_ROOT

__all__ = ["write_key_submission"]


def write_key_submission(out: str | os.PathLike, *, zip_it: bool = True) -> Path:
    """Write the answer-key submission to ``out/hw4_key/`` (and ``out/hw4_key.zip``); return it.

    The notebooks are copied from notebooks/key when all of them are there, else built from
    solutions/ with ``kit.notebooks`` (the same build that writes notebooks/key).  The folder is
    made mode 0700 and every file 0600, whatever the umask; ``out`` itself, when this makes it,
    is 0700 too.
    """
    old = os.umask(0o077)
    try:
        return _write(Path(out), zip_it)
    finally:
        os.umask(old)


def _write(out: Path, zip_it: bool) -> Path:
    folder = out / "hw4_key"
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True, mode=0o700)
    os.chmod(folder, 0o700)
    key_dir = KIT_ROOT / "notebooks" / "key"
    if all((key_dir / f"{stem}.ipynb").is_file() for stem in NOTEBOOKS):
        for stem in NOTEBOOKS:
            shutil.copyfile(key_dir / f"{stem}.ipynb", folder / f"{stem}.ipynb")
    else:
        import nbformat

        from kit.notebooks import build_notebook

        for stem in NOTEBOOKS:
            nbformat.write(build_notebook(stem, "key"), folder / f"{stem}.ipynb")
    for p in folder.iterdir():
        os.chmod(p, 0o600)
    if not zip_it:
        return folder
    archive = out / "hw4_key.zip"
    archive.unlink(missing_ok=True)
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as zf:
        for p in sorted(folder.glob("*.ipynb")):
            zf.write(p, p.name)
    os.chmod(archive, 0o600)
    return archive
