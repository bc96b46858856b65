"""A local MathJax 2 to typeset the notebooks' math offline.

Searched: ``$HW4_MATHJAX``, the ``jupyter_server_mathjax`` package, Debian's
``/usr/share/javascript/mathjax``, ``/usr/share/mathjax``.  In Google Colab,
:func:`ensure_mathjax` pip-installs ``jupyter-server-mathjax`` the first time.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

from .browser import in_colab

__all__ = ["MathJaxNotFoundError", "find_mathjax", "ensure_mathjax"]

MATHJAX_HELP = ("no local MathJax 2 found to typeset the math offline. Install one:\n"
                "  pip install jupyter-server-mathjax        (any system)\n"
                "  apt-get install libjs-mathjax fonts-mathjax (Debian/Ubuntu)\n"
                "or point HW4_MATHJAX at a folder holding MathJax.js.")


class MathJaxNotFoundError(RuntimeError):
    """No local MathJax 2 copy could be found; the message says how to install one."""


def ensure_mathjax(*, install: bool | None = None) -> Path:
    """Like :func:`find_mathjax`, but pip-installs ``jupyter-server-mathjax`` when none is found
    (by default only in Google Colab)."""
    try:
        return find_mathjax()
    except MathJaxNotFoundError:
        if not (in_colab() if install is None else install):
            raise
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "jupyter-server-mathjax"], check=True)
    importlib.invalidate_caches()
    return find_mathjax()


def find_mathjax() -> Path:
    """Folder of a local MathJax 2 that has the TeX config and the STIX-Web fonts used here.

    Searched: ``$HW4_MATHJAX``, the ``jupyter_server_mathjax`` package, Debian's
    ``/usr/share/javascript/mathjax``, ``/usr/share/mathjax``.

    Raises
    ------
    MathJaxNotFoundError
        When no usable copy is found; the message says how to install one.
    """
    candidates = []
    if env := os.environ.get("HW4_MATHJAX"):
        candidates.append(Path(env).parent if env.endswith(".js") else Path(env))
    spec = importlib.util.find_spec("jupyter_server_mathjax")
    if spec and spec.origin:
        candidates.append(Path(spec.origin).parent / "static")
    candidates += [Path("/usr/share/javascript/mathjax"), Path("/usr/share/mathjax")]
    for folder in candidates:
        if ((folder / "MathJax.js").is_file()
                and (folder / "config" / "TeX-AMS-MML_HTMLorMML-full.js").is_file()
                and (folder / "fonts" / "HTML-CSS" / "STIX-Web" / "woff").is_dir()):
            return folder
    raise MathJaxNotFoundError(MATHJAX_HELP)
