"""How the kit prints numbers for people, and how it writes a file so that a reader never sees half."""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

__all__ = ["fmt", "points", "private_folder", "write_atomic"]


def fmt(x, digits: int = 3) -> str:
    """A measured figure for a report or feedback: ``digits`` significant digits.

    Small figures come in exponent form (3.09e-04, never a long run of digits that could carry
    data out of the sandbox); "infinite" and "not finite" are spelled out; anything that is not
    a number comes back as ``str(x)``.
    """
    try:
        v = float(x)
    except (TypeError, ValueError):
        return str(x)
    if math.isnan(v):
        return "not finite"
    if math.isinf(v):
        return "infinite"
    if v != 0 and abs(v) < 1e-2:
        return f"{v:.{max(digits - 1, 0)}e}"
    return f"{v:.{digits}g}"


def points(x: float) -> str:
    """A score for a CSV or a summary: at most four decimals, no trailing zeros ("7.5", "10")."""
    return f"{round(float(x), 4):g}"


def write_atomic(path: str | os.PathLike, text: str | bytes, *, mode: int = 0o644) -> Path:
    """Write ``text`` (str as UTF-8, or bytes) to ``path`` through a temporary file in the same
    folder and a rename.

    A crash or a kill leaves either the old file or the new one, never a torn one.  ``mode`` is
    applied before the rename, so a private file is never readable by others, not even briefly.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            if isinstance(text, str):
                text = text.encode("utf-8")
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def private_folder(path: str | os.PathLike) -> Path:
    """``path`` as a folder only its owner can enter (0700), made with its parents if missing.

    An existing folder is made private too: what the staff write there (every student's code or
    scores) must not become readable to others because the folder was made by hand first.
    """
    path = Path(path)
    path.mkdir(mode=0o700, parents=True, exist_ok=True)
    os.chmod(path, 0o700)
    return path
