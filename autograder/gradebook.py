"""The class's gradebook: ``grades.csv`` from the batch records of an output folder."""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from core.text import points

from .results import autograded_question_ids, csv_header

__all__ = ["BatchRecord", "earlier_records", "write_grades_csv"]


@dataclass(frozen=True)
class BatchRecord:
    """One submission of a batch: where its results are, its scores, and whether it was graded now."""

    name: str
    path: Path
    folder: Path
    score: float
    scores: dict
    failure: str | None
    skipped: bool
    seconds: float


def write_grades_csv(path: Path, records: Sequence) -> Path:
    """``student_id, total, <one column per autograded question>``, one line per record."""
    ids = autograded_question_ids()
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(csv_header(ids))
        for r in records:
            scores = [0.0 if r.failure else float(r.scores.get(q, 0.0)) for q in ids]
            writer.writerow([r.name, points(0.0 if r.failure else r.score)] + [points(s) for s in scores])
    return path


def earlier_records(out: Path, exclude: set[str]) -> list:
    """Submissions graded into ``out`` by earlier batches, so that grades.csv lists the whole class."""
    found = []
    for state_file in sorted(out.glob("*/grading.json")):
        name = state_file.parent.name
        if name in exclude:
            continue
        try:
            state = json.loads(state_file.read_text(encoding="utf-8"))
            found.append(BatchRecord(name, Path(state.get("path", "")), state_file.parent, float(state["score"]),
                                     {k: float(v) for k, v in dict(state["scores"]).items()}, state.get("failure"),
                                     True, 0.0))
        except (OSError, ValueError, KeyError, TypeError):
            continue
    return found
