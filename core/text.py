"""How the kit prints numbers for people, and how it writes a file so that a reader never sees half."""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

__all__ = ["fmt", "points", "write_atomic"]


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


def write_atomic(path: str | os.PathLike, text: str, *, mode: int = 0o644) -> Path:
    """Write ``text`` to ``path`` through a temporary file in the same folder and a rename.

    A crash or a kill leaves either the old file or the new one, never a torn one.  ``mode`` is
    applied before the rename, so a private file is never readable by others, not even briefly.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
