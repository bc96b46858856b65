"""Regrade with a diff: grade a class again beside its published results, see whose score moved and
why, and publish only when the staff accept it.

    python -m autograder regrade OLD_DIR --into NEW_DIR [SUBMISSION...]   # grade again, write the diff
    python -m autograder accept NEW_DIR --into OLD_DIR                    # publish the regrade

``regrade`` grades the submissions (by default the ones recorded in ``OLD_DIR``'s results) into
``NEW_DIR`` with today's grader (tests, thresholds, secret, data, kit version as configured now)
and writes, in ``NEW_DIR``, ``regrade_diff.csv``, ``regrade_diff.md`` and ``regrade_diff.html``:
one line per student and question whose score changed (``total`` included), old and new score,
the checks whose score changed (the why) and how the two configurations differ.  ``OLD_DIR`` is
not touched.  ``accept`` moves ``OLD_DIR``'s results to ``OLD_DIR/.history/<time>/`` and copies
``NEW_DIR``'s in their place (grades.csv included).

The diff is the staff's alone (files 0600): it names students and scores.  Names and the reasons
of failures come from submissions, so every cell, line and table passes ``core.untrusted``.
"""

from __future__ import annotations

import json
import os
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

from core.text import points, private_folder, write_atomic
from core.untrusted import csv_text, for_html, for_markdown

from autograder.inputs.config import configuration_changes
from .gradebook import read_state

__all__ = ["MARKER", "Change", "accept", "diff_folders", "regrade", "write_diff"]

MARKER = "regrade.json"
_TOL = 1e-6
_RESULT_FILES = ("grades.csv", "summary.md", "configuration.json")
_PRIVATE = 0o600


@dataclass(frozen=True)
class Change:
    """One student's score on one question (or "total") that differs between two gradings.

    old, new: points (None: not graded there); why: the checks whose score changed, as
    "name: old -> new"; configuration: how the two results' configurations differ.
    """

    student: str
    question: str
    old: float | None
    new: float | None
    why: tuple[str, ...]
    configuration: tuple[str, ...]

    @property
    def change(self) -> float | None:
        return None if self.old is None or self.new is None else self.new - self.old


def _tests_of(folder: Path, state: dict) -> dict[tuple[str, str], tuple[float, float]]:
    """(question, check name) -> (score, max_score) of a graded submission."""
    if state.get("failure"):
        return {}
    if isinstance(state.get("tests"), list):
        return {(t["question"], t["name"]): (float(t["score"]), float(t["max_score"])) for t in state["tests"]}
    try:  # results written before grading.json listed the checks: Gradescope's names "Q2 check"
        data = json.loads((folder / "results.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    found = {}
    for t in data.get("tests", []):
        qid, _, name = str(t.get("name", "")).partition(" ")
        found[(qid, name.removesuffix(" (extra credit)"))] = (float(t["score"]), float(t["max_score"]))
    return found


def _graded(folder: Path) -> dict[str, tuple[Path, dict]]:
    out = {}
    for state_file in sorted(Path(folder).glob("*/grading.json")):
        state = read_state(state_file.parent)
        if state is not None:
            out[state_file.parent.name] = (state_file.parent, state)
    return out


def _scores(state: dict | None) -> dict[str, float]:
    if state is None:
        return {}
    failed = bool(state.get("failure"))
    scores = {q: 0.0 if failed else float(s) for q, s in dict(state.get("scores", {})).items()}
    scores["total"] = 0.0 if failed else float(state.get("score", 0.0))
    return scores


def diff_folders(old: str | os.PathLike, new: str | os.PathLike) -> list[Change]:
    """Every (student, question) whose score differs between graded folders ``old`` and ``new``.

    Students graded in only one folder get one "total" line with None on the other side.
    """
    before, after = _graded(Path(old)), _graded(Path(new))
    changes: list[Change] = []
    for student in sorted(set(before) | set(after)):
        (fo, so), (fn, sn) = before.get(student, (None, None)), after.get(student, (None, None))
        config = tuple(configuration_changes(so.get("configuration"), sn.get("configuration"))) if so and sn else ()
        if so is None or sn is None:
            side = "not in the regrade" if sn is None else "not in the published grades"
            changes.append(Change(student, "total", _scores(so).get("total"), _scores(sn).get("total"),
                                  (side,), config))
            continue
        old_scores, new_scores = _scores(so), _scores(sn)
        old_tests, new_tests = _tests_of(fo, so), _tests_of(fn, sn)
        questions = [q for q in new_scores if q != "total"] + [q for q in old_scores if q not in new_scores]
        for qid in [*questions, "total"]:
            a, b = old_scores.get(qid, 0.0), new_scores.get(qid, 0.0)
            if abs(a - b) <= _TOL:
                continue
            changes.append(Change(student, qid, a, b, _why(qid, so, sn, old_tests, new_tests), config))
    return changes


def _why(qid: str, so: dict, sn: dict, old_tests: dict, new_tests: dict) -> tuple[str, ...]:
    why = []
    if so.get("failure") != sn.get("failure"):
        if so.get("failure"):
            why.append(f"was not graded before ({so['failure']})")
        if sn.get("failure"):
            why.append(f"could not be graded now ({sn['failure']})")
    keys = [k for k in new_tests if qid in ("total", k[0])]
    keys += [k for k in old_tests if qid in ("total", k[0]) and k not in new_tests]
    for k in keys:
        name = k[1] if qid != "total" else f"{k[0]} {k[1]}"
        a, b = old_tests.get(k), new_tests.get(k)
        if a is None:
            why.append(f"{name}: new check, {points(b[0])} / {points(b[1])}")
        elif b is None:
            why.append(f"{name}: check removed (was {points(a[0])} / {points(a[1])})")
        elif abs(a[0] - b[0]) > _TOL or abs(a[1] - b[1]) > _TOL:
            why.append(f"{name}: {points(a[0])} / {points(a[1])} -> {points(b[0])} / {points(b[1])}")
    return tuple(why)


def write_diff(folder: str | os.PathLike, changes: list[Change], *, old: Path, new: Path,
               config_changes: list[str], students: int) -> dict[str, Path]:
    """``regrade_diff.csv``, ``.md`` and ``.html`` in ``folder``; returns their paths by suffix."""
    folder = Path(folder)
    table = [["student_id", "question", "old", "new", "change", "why", "configuration"]] + [
        [c.student, c.question, "" if c.old is None else points(c.old), "" if c.new is None else points(c.new),
         "" if c.change is None else points(c.change), "; ".join(c.why), "; ".join(c.configuration)]
        for c in changes]
    moved = sorted({c.student for c in changes})
    head = [f"Published grades: {old}", f"Regrade: {new}",
            f"{len(moved)} of {students} students changed score" + (f": {', '.join(moved)}" if moved else ""),
            "Configuration changes: " + ("; ".join(config_changes) if config_changes else "none")]
    md = ["# Regrade diff", ""] + [f"- {for_markdown(line, newlines=False)}" for line in head] + [""]
    md += [f"Nothing is published until `python -m autograder accept {new} --into {old}`.", ""]
    if changes:
        md += ["| Student | Question | Old | New | Change | Why |", "|---|---|---|---|---|---|"]
        for c in changes:
            cells = [c.student, c.question, "-" if c.old is None else points(c.old),
                     "-" if c.new is None else points(c.new), "-" if c.change is None else f"{c.change:+g}",
                     "<br>".join(for_markdown(w, newlines=False) for w in c.why) or "-"]
            # The student's name is escaped, and each reason (above); the question and the figures
            # are the kit's ("-1" stays a number), and so is the <br> between reasons.
            md.append("| " + " | ".join(for_markdown(x, newlines=False) if k == 0 else x for k, x in enumerate(cells))
                      + " |")
    else:
        md.append("No score changed.")
    rows = "".join(
        "<tr>" + "".join(f"<td>{for_html(x)}</td>" for x in (
            c.student, c.question, "-" if c.old is None else points(c.old), "-" if c.new is None else points(c.new),
            "-" if c.change is None else f"{c.change:+g}")) + "<td>" + "<br>".join(for_html(w) for w in c.why)
        + "</td></tr>\n" for c in changes)
    page = ("<!doctype html><html><head><meta charset='utf-8'><title>Regrade diff</title><style>"
            "body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}"
            "td,th{border:1px solid #ccc;padding:4px 8px;vertical-align:top}</style></head><body>"
            "<h1>Regrade diff</h1><ul>" + "".join(f"<li>{for_html(line)}</li>" for line in head) + "</ul>"
            + ("<table><tr><th>Student</th><th>Question</th><th>Old</th><th>New</th><th>Change</th><th>Why</th></tr>\n"
               + rows + "</table>" if changes else "<p>No score changed.</p>") + "</body></html>\n")
    return {"csv": write_atomic(folder / "regrade_diff.csv", csv_text(table), mode=_PRIVATE),
            "md": write_atomic(folder / "regrade_diff.md", "\n".join(md) + "\n", mode=_PRIVATE),
            "html": write_atomic(folder / "regrade_diff.html", page, mode=_PRIVATE)}


def regrade(old: str | os.PathLike, new: str | os.PathLike, paths=None, **grade_options) -> dict:
    """Grade the class of ``old`` again into ``new`` and write the diff there.

    paths: the submissions (default: those recorded in ``old``'s results, which must still exist);
    grade_options: passed to ``autograder.channels.batch.grade_batch`` (config, jobs, extra_tests...).
    Returns ``{"records", "changes", "files", "configuration_changes"}``.

    Raises ValueError when ``old`` holds no graded submission or ``new`` is ``old``.
    """
    from .batch import grade_batch
    from .journal import folder_configuration

    old, new = Path(old).resolve(), Path(new).resolve()
    if old == new:
        raise ValueError(f"new: expected a folder other than the published {old}, got the same")
    before = _graded(old)
    if not before:
        raise ValueError(f"old: expected a folder of graded submissions (*/grading.json), got none in {old}")
    if paths is None:
        paths = [Path(s.get("path", "")) for _, s in before.values()]
        missing = [str(p) for p in paths if not p.exists()]
        if missing:
            raise FileNotFoundError(f"paths: the recorded submissions are gone: {missing[:5]}; give them explicitly")
    private_folder(new)  # results and scores of the class: private also when called from Python
    records = grade_batch(paths, new, **grade_options)
    changes = diff_folders(old, new)
    config_changes = configuration_changes(folder_configuration(old), folder_configuration(new))
    files = write_diff(new, changes, old=old, new=new, config_changes=config_changes,
                       students=len(set(before) | {r.name for r in records}))
    write_atomic(new / MARKER, json.dumps({"old": str(old), "accepted": None,
                                           "changed": sorted({c.student for c in changes})}, indent=2),
                 mode=_PRIVATE)
    return {"records": records, "changes": changes, "files": files, "configuration_changes": config_changes}


def accept(new: str | os.PathLike, into: str | os.PathLike) -> Path:
    """Publish the regrade in ``new``: ``into``'s results go to ``into/.history/<time>/`` and
    ``new``'s are copied in their place.  Returns the history folder.

    Raises ValueError when ``new`` is not a finished regrade of ``into``.
    """
    from .journal import JOURNAL
    from .journal import lock as _lock

    new, into = Path(new).resolve(), Path(into).resolve()
    try:
        marker = json.loads((new / MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        raise ValueError(f"new: expected a regrade folder (with {MARKER}), got {new}") from None
    if Path(marker.get("old", "")) != into:
        raise ValueError(f"into: expected the folder this regrade compared with ({marker.get('old')}), got {into}")
    if any((new / JOURNAL).glob("*.json")):
        raise ValueError(f"new: the regrade in {new} did not finish (submissions in flight); run it again first")
    lock_new, lock_into = _lock(new), _lock(into)
    try:
        history = into / ".history" / time.strftime("%Y%m%d-%H%M%S")
        history.mkdir(parents=True)
        for state_file in sorted(into.glob("*/grading.json")):
            os.rename(state_file.parent, history / state_file.parent.name)
        for name in _RESULT_FILES:
            if (into / name).exists():
                os.rename(into / name, history / name)
        for state_file in sorted(new.glob("*/grading.json")):
            shutil.copytree(state_file.parent, into / state_file.parent.name)
        for name in (*_RESULT_FILES, "regrade_diff.csv", "regrade_diff.md", "regrade_diff.html"):
            if (new / name).exists():
                shutil.copy2(new / name, into / name)
        marker["accepted"] = time.strftime("%Y-%m-%d %H:%M:%S")
        write_atomic(new / MARKER, json.dumps(marker, indent=2), mode=_PRIVATE)
    finally:
        os.close(lock_into)
        os.close(lock_new)
    return history
