"""One anonymised example picture per named mistake of the class report.

For each named mistake (question, name) the report takes the picture of that question from the
first of its students (by name) whose graded folder has one: ``<graded>/<student>/figures/``,
written beside the results by ``autograder.feedback.page``.  What is kept is the PNG and the
picture's alt text only, both drawn by the grader from numbers (``starter.checks.pictures.draw``):
no student name, file name or code is in them, and the report shows no name beside them.
"""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["MAX_BYTES", "mistake_examples"]

MAX_BYTES = 2_000_000   # a larger file in a graded folder is not the grader's: not shown
_INDEX = ("figures", "figures.json")


def _picture(folder: Path, qid: str) -> tuple[bytes, str] | None:
    try:
        entry = json.loads(folder.joinpath(*_INDEX).read_text(encoding="utf-8")).get(qid)
        name = entry.get("file") if isinstance(entry, dict) else None
        if not isinstance(name, str) or "/" in name or name.startswith("."):
            return None
        path = folder / _INDEX[0] / name
        if path.is_symlink() or path.stat().st_size > MAX_BYTES:
            return None
        png = path.read_bytes()
    except (OSError, ValueError, AttributeError):
        return None
    alt = entry.get("alt") if isinstance(entry.get("alt"), str) and entry.get("alt").strip() else f"{qid} picture"
    return (png, alt) if png.startswith(b"\x89PNG\r\n\x1a\n") else None


def mistake_examples(graded: str | Path, mistakes) -> dict[tuple[str, str], tuple[bytes, str]]:
    """(question, mistake) -> (PNG bytes, alt text) of one student who made it, for each of
    ``mistakes`` (``((question, name), students)`` pairs) with a picture of that question."""
    graded = Path(graded)
    out = {}
    for (qid, name), students in mistakes:
        for student in sorted(students):
            found = _picture(graded / student, qid)
            if found is not None:
                out[(qid, name)] = found
                break
    return out
