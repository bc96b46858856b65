"""The files of a folder a student handed in, listed without recursion and without following links.

``os.walk`` and ``Path.rglob`` recurse in Python 3.11: a hand-in holding a folder a thousand levels
deep raised RecursionError wherever a submission's files were listed (reading it, its digest, the
Gradescope run, the look-alike check).  Here the walk keeps its own stack, never enters a link to
a folder, and stops descending at ``MAX_DEPTH`` levels (no homework needs more); what it passed
over is counted, never raised.
"""

from __future__ import annotations

import os
import stat
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["MAX_DEPTH", "Listing", "list_files"]

MAX_DEPTH = 64


@dataclass
class Listing:
    """files: (path, lstat) of every regular file, in the order of a top-down ``os.walk`` with names
    sorted (a folder's files, then each subfolder in turn); links: paths of the symbolic links met
    (files or folders, never followed), in the same order; too_deep: folders
    not entered because they lie deeper than ``MAX_DEPTH``; unreadable: folders that could not be
    listed (or entries that could not be looked at); truncated: the walk stopped at ``max_entries`` files and links."""

    files: list[tuple[Path, os.stat_result]] = field(default_factory=list)
    links: list[Path] = field(default_factory=list)
    too_deep: int = 0
    unreadable: int = 0
    truncated: bool = False


def list_files(root: str | os.PathLike, *, max_depth: int = MAX_DEPTH, max_entries: int | None = None) -> Listing:
    """Every regular file under the folder ``root`` (see ``Listing``), at most ``max_entries`` files
    and links when given."""
    if max_depth < 1:
        raise ValueError(f"max_depth: expected at least 1, got {max_depth}")
    out = Listing()
    stack = [(Path(root), 1)]
    while stack:
        folder, depth = stack.pop()
        try:
            entries = sorted(os.scandir(folder), key=lambda e: e.name)
        except OSError:
            out.unreadable += 1
            continue
        below = []
        for entry in entries:
            path = Path(entry.path)
            try:
                st = entry.stat(follow_symlinks=False)
            except OSError:   # gone meanwhile, or its path past PATH_MAX
                out.unreadable += 1
                continue
            if max_entries is not None and len(out.files) + len(out.links) >= max_entries and (
                    stat.S_ISLNK(st.st_mode) or stat.S_ISREG(st.st_mode)):
                out.truncated = True
                return out
            if stat.S_ISLNK(st.st_mode):
                out.links.append(path)
            elif stat.S_ISDIR(st.st_mode):
                if depth < max_depth:
                    below.append((path, depth + 1))
                else:
                    out.too_deep += 1
            elif stat.S_ISREG(st.st_mode):
                out.files.append((path, st))
        stack.extend(reversed(below))   # the first subfolder is listed next
    return out
