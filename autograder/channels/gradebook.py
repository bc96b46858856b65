"""The class's gradebook: ``grades.csv`` and ``summary.md`` from the batch records of an output folder.

``grades.csv`` keeps the columns an import expects (``student_id, total, Q2, ...``); how the
folder was graded (configuration, a development secret, isolation levels, failures) is in
``summary.md`` and ``configuration.json`` beside it.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from core.text import points, write_atomic
from core.untrusted import csv_text, for_markdown

from autograder.feedback.results import autograded_question_ids, csv_header

__all__ = ["BatchRecord", "earlier_records", "read_state", "staff_of", "write_grades_csv", "write_summary"]


@dataclass(frozen=True)
class BatchRecord:
    """One submission of a batch: where its results are, its scores, and whether it was graded now.

    configuration_key: ``autograder.inputs.config.configuration_key`` of the grading (None: not recorded);
    isolation: the sandbox level it ran at (None when no sandbox ran); removed: (entries, bytes) its
    code left in the machine's shared temporary folders, removed by the grader; over_quota: what
    went past the sandbox's disk quota; not_removed: what it left that could not be removed
    (``"<path>: <why>"``); survived: what of its uid outlived the sweep (all for staff, from
    ``staff_of``).
    """

    name: str
    path: Path
    folder: Path
    score: float
    scores: dict
    failure: str | None
    skipped: bool
    seconds: float
    configuration_key: str | None = None
    isolation: str | None = None
    removed: tuple[int, int] = (0, 0)
    over_quota: tuple[str, ...] = ()
    not_removed: tuple[str, ...] = ()
    survived: tuple[str, ...] = ()


def write_grades_csv(path: Path, records: Sequence) -> Path:
    """``student_id, total, <one column per autograded question>``, one line per record (atomic)."""
    ids = autograded_question_ids()
    rows = [csv_header(ids)]
    for r in records:
        scores = [0.0 if r.failure else float(r.scores.get(q, 0.0)) for q in ids]
        rows.append([r.name, points(0.0 if r.failure else r.score)] + [points(s) for s in scores])
    return write_atomic(path, csv_text(rows))


def read_state(folder: Path) -> dict | None:
    """The ``grading.json`` of a submission's folder, or None when missing or unreadable."""
    try:
        state = json.loads((Path(folder) / "grading.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return state if isinstance(state, dict) else None


def staff_of(staff) -> dict:
    """The BatchRecord fields of a submission's staff notes: ``removed`` (with its ``not_removed``),
    ``over_quota`` and ``survived``."""
    staff = staff if isinstance(staff, dict) else {}
    removed = staff.get("removed") if isinstance(staff.get("removed"), dict) else {}

    def lines(value) -> tuple[str, ...]:
        return tuple(str(x) for x in value) if isinstance(value, list) else ()

    return {"removed": (int(removed.get("entries", 0) or 0), int(removed.get("bytes", 0) or 0)),
            "over_quota": lines(staff.get("over_quota")), "not_removed": lines(removed.get("not_removed")),
            "survived": lines(staff.get("survived"))}


def record_of(folder: Path, state: dict) -> BatchRecord:
    """The BatchRecord of a finished ``grading.json`` (KeyError/TypeError/ValueError when malformed)."""
    iso = state.get("isolation")
    return BatchRecord(folder.name, Path(state.get("path", "")), folder, float(state["score"]),
                       {k: float(v) for k, v in dict(state["scores"]).items()}, state.get("failure"), True, 0.0,
                       state.get("configuration_key"), iso.get("level") if isinstance(iso, dict) else None,
                       **staff_of(state.get("staff")))


def earlier_records(out: Path, exclude: set[str], key: str | None = None) -> list:
    """Submissions graded into ``out`` by earlier batches, so that grades.csv lists the whole class.

    With ``key``, only those graded with that configuration key.
    """
    found = []
    for state_file in sorted(Path(out).glob("*/grading.json")):
        name = state_file.parent.name
        if name in exclude:
            continue
        state = read_state(state_file.parent)
        if state is None or (key is not None and state.get("configuration_key") != key):
            continue
        try:
            found.append(record_of(state_file.parent, state))
        except (ValueError, KeyError, TypeError):
            continue
    return found


def write_summary(path: Path, records: Sequence, configuration: dict, *, cancelled: Sequence[str] = (),
                  note: str = "", library_calls: dict | None = None) -> Path:
    """``summary.md``: the configuration, a warning for a development secret, counts, failures, and
    the library calls to look at (``library_calls``: student -> (LibraryCall list, notes), from
    ``autograder.review.library_calls.find_in_class``; None: not looked for)."""
    c = configuration
    data = c.get("data") or {}
    levels = sorted({r.isolation for r in records if r.isolation})
    failed = [r for r in records if r.failure]
    lines = ["# Grading summary", ""]
    if c.get("dev_secret"):
        lines += ["**WARNING: graded with the public DEVELOPMENT secret** (hidden scenes anyone can make): "
                  "these grades are not for publishing. Set HW4_GRADER_SECRET or HW4_GRADER_CONFIG.", ""]
    if len(levels) > 1:
        lines += [f"**Warning: submissions ran at different isolation levels: {', '.join(levels)}.**", ""]
    if note:
        lines += [note, ""]
    lines += [
        f"- submissions: {len(records)} ({sum(not r.skipped for r in records)} graded by the last batch, "
        f"{len(failed)} failed, {len(cancelled)} cancelled and not recorded)",
        f"- configuration: {c.get('key')} (grader {c.get('grader_version')}, kit {c.get('kit_version')})",
        f"- secret fingerprint: {c.get('secret_fingerprint')}" + (" (development secret)" if c.get("dev_secret") else ""),
        f"- data: {'default data' if data.get('default_data') else 'no default data'}"
        + (f" + official data {data.get('official_data')}" if data.get("official_data") else ", no official data"),
        f"- hidden tests: {(c.get('tests') or {}).get('digest')}"
        + (" (with extra tests)" if (c.get("tests") or {}).get("extra") else ""),
        f"- isolation: {', '.join(levels) or 'none ran'}",
    ]
    if failed:
        lines += ["", "## Could not be graded", ""] + [f"- {for_markdown(r.name, newlines=False)}: "
                                                        f"{for_markdown(r.failure)}" for r in failed]
    quota = [r for r in records if r.over_quota]
    if quota:
        lines += ["", "## Past the sandbox's disk quota (those calls failed)", ""]
        lines += [f"- {for_markdown(r.name, newlines=False)}: {for_markdown(line)}"
                  for r in quota for line in r.over_quota[:5]]
    left = [r for r in records if r.removed[0]]
    if left:
        lines += ["", "## Left in the shared temporary folders (/tmp, /var/tmp, /dev/shm, /run/lock), removed by the "
                  "grader", ""]
        lines += [f"- {for_markdown(r.name, newlines=False)}: {r.removed[0]} files and folders, "
                  f"{r.removed[1] / 2**20:.1f} MB" for r in left]
    stuck = [r for r in records if r.not_removed]
    if stuck:
        lines += ["", "## Left by the code and NOT removed (remove by hand)", ""]
        lines += [f"- {for_markdown(r.name, newlines=False)}: {for_markdown(line, newlines=False)}"
                  for r in stuck for line in r.not_removed[:10]]
    survived = [r for r in records if r.survived]
    if survived:
        lines += ["", "## Processes that outlived the sandbox's sweep (their uid was not used again)", ""]
        lines += [f"- {for_markdown(r.name, newlines=False)}: {for_markdown(line, newlines=False)}"
                  for r in survived for line in r.survived[:5]]
    if cancelled:
        lines += ["", "## Cancelled (graded again on resume)", ""] + [f"- {for_markdown(n, newlines=False)}"
                                                                       for n in cancelled]
    if library_calls is not None:
        lines += ["", "## Library calls to look at", ""] + library_calls_markdown(library_calls)
    return write_atomic(path, "\n".join(lines) + "\n")


def library_calls_markdown(found: dict) -> list[str]:
    """The lines of summary.md's library-call section (student -> (LibraryCall list, notes))."""
    from autograder.review.library_calls import markdown_code

    with_calls = {s: calls for s, (calls, _) in found.items() if calls}
    lines = [f"Uses of library functions that do what the homework asks students to write, found in the code "
             f"(not run): {len(with_calls)} of {len(found)} submissions. A reason to read the code, not a "
             f"finding: no points were taken for them, and students are not shown this list. The names "
             f"looked for are the config's `library_calls` (default: autograder.review.library_calls).", ""]
    for student in sorted(with_calls):
        for c in with_calls[student]:
            inside = f" in {markdown_code(c.function)}" if c.function else ""
            does = f" ({c.replaces})" if c.replaces else ""
            lines.append(f"- {for_markdown(student, newlines=False)}: {markdown_code(c.name)}{does}, {c.kind}"
                         f"{inside}: {markdown_code(c.code)} ({for_markdown(c.where, newlines=False)})")
    unread = sorted(s for s, (_, notes) in found.items() if notes)
    if unread:  # the reasons are in each note; here, only whose list may be incomplete
        lines += ["", f"Code not read in full (a cell that does not parse, a file gone): {for_markdown(', '.join(unread), newlines=False)}."]
    return lines
