"""The class report of a graded folder: who passed what, the named mistakes, histograms, gradebooks.

Reads ``<graded>/<student>/results.json`` (Gradescope's schema, as the grader writes it: tests
with name "Q2 <check>", score, max_score, status, output) and writes into ``out``:

- ``tests.csv``: per question and per test, how many results have it and the share that passed;
- ``mistakes.csv``: each known mistake the grader recorded for a check (the check's
  ``extra_data.mistakes`` in results.json: codes of ``judging.mistakes.KNOWN_MISTAKES``, written
  from the judging's own Mistakes; feedback, which quotes students, is not read for them) with its
  question, catalogue name, count and the students who made it.  Only a check written by a grader
  that did not record its mistakes is read as before: the catalogue's names in its feedback;
- ``histogram_<question>.png`` (and ``histogram_total.png``): scores per question;
- ``report.html``: all of the above on one page, the histograms embedded (works offline);
- ``grades.csv``: ``student_id, total, Q2, ...`` (copied from the graded folder when it has one);
- ``canvas.csv``: the columns of Canvas's gradebook import (Student, ID, SIS User ID, SIS Login
  ID, Section, then one column per assignment, with a "Points Possible" row).  Without a roster
  the student's folder name goes in SIS Login ID; with ``roster`` (a Canvas gradebook export)
  the students are matched on SIS Login ID, SIS User ID or ID and their row is filled from it;
- ``library_calls.csv``: each use of a library function that does what the homework asks students
  to write (``autograder.review.library_calls``), found in the code each ``grading.json`` names
  (staff's files; a submission moved since is listed as not read), also a section of the page.
  For the staff: no points are taken, and nothing of it reaches a student's feedback.

The folder and its files are the staff's alone (0700 and 0600, like the graded folder): they hold
every student's scores.  Names, test names, code and feedback come from submissions: every CSV
cell passes ``core.untrusted.for_csv_cell`` and every text of the page ``for_html``.
"""

from __future__ import annotations

import base64
import csv
import io
import json
import re
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from core.manifest import QUESTIONS
from core.text import points, private_folder, write_atomic
from core.untrusted import csv_text, for_html
from judging.mistakes import KNOWN_MISTAKES

from .examples import mistake_examples
from .html import STYLE
from .library_calls import find_in_class

__all__ = ["ClassReport", "CANVAS_COLUMNS", "load_results", "build_report", "write_report"]

CANVAS_COLUMNS = ("Student", "ID", "SIS User ID", "SIS Login ID", "Section")
_CATALOGUE = {code: name for code, (name, _) in KNOWN_MISTAKES.items()}
# Only for a check whose mistakes were not recorded (a results.json of a grader that did not
# record them): the catalogue's names in its feedback, as the report read them before.  A student's
# exception message can imitate one there; a recorded check is never read this way.
_UNRECORDED_PATTERN = re.compile(
    r"(?:known|likely) mistake:\s*(" + "|".join(re.escape(name) for name in
                                                sorted(_CATALOGUE.values(), key=lambda v: -len(v)))
    + r")\s*(?:\.|$)", re.IGNORECASE | re.MULTILINE)
_CATALOGUE_NAMES = {name.lower(): name for name in _CATALOGUE.values()}
_QUESTION_IDS = tuple(q.id for q in QUESTIONS if not q.by_hand)
_EXTRA = {q.id for q in QUESTIONS if q.extra_credit}
_POINTS = {q.id: q.points for q in QUESTIONS}
_PRIVATE = 0o600  # every student's scores: the staff's alone


@dataclass
class ClassReport:
    """What the class got.

    students: names in order; scores: question -> {student: score}; totals: student -> total;
    failures: student -> why grading failed; tests: (question, test name) -> [passed, seen];
    mistakes: (question, mistake name) -> sorted students.
    """

    students: list = field(default_factory=list)
    scores: dict = field(default_factory=lambda: defaultdict(dict))
    totals: dict = field(default_factory=dict)
    failures: dict = field(default_factory=dict)
    tests: dict = field(default_factory=dict)
    mistakes: dict = field(default_factory=lambda: defaultdict(set))

    def pass_rate(self, question: str, test: str) -> float:
        passed, seen = self.tests[(question, test)]
        return passed / seen if seen else 0.0


def load_results(graded: str | Path) -> dict[str, dict]:
    """student -> parsed results.json of every ``graded/<student>/results.json`` (sorted by name)."""
    graded = Path(graded)
    if not graded.is_dir():
        raise ValueError(f"graded: expected a folder of graded submissions, got {str(graded)!r}")
    out = {}
    for p in sorted(graded.glob("*/results.json")):
        try:
            out[p.parent.name] = json.loads(p.read_text())
        except (OSError, ValueError):
            out[p.parent.name] = {"score": 0, "tests": [], "extra_data": {"failure": "results.json unreadable"}}
    return out


def _split_name(name: str) -> tuple[str, str]:
    qid, _, rest = name.partition(" ")
    rest = rest.removesuffix(" (extra credit)")
    return qid, rest


def _mistakes_of(test: dict) -> list[str]:
    """The catalogue names of the known mistakes the grader recorded for ``test`` (one test of
    results.json): its ``extra_data.mistakes`` codes, unknown ones left out.

    A test without that record (written by a grader that did not record mistakes) falls back to
    the catalogue's names in its feedback.
    """
    extra = test.get("extra_data")
    if isinstance(extra, dict) and "mistakes" in extra:
        codes = extra["mistakes"] if isinstance(extra["mistakes"], list) else []
        return [_CATALOGUE[c] for c in codes if isinstance(c, str) and c in _CATALOGUE]
    return [_CATALOGUE_NAMES[m.lower()] for m in _UNRECORDED_PATTERN.findall(str(test.get("output", "")))]


def build_report(results: dict[str, dict]) -> ClassReport:
    """Tally ``results`` (student -> results.json dict)."""
    rep = ClassReport(students=list(results))
    for student, data in results.items():
        failure = (data.get("extra_data") or {}).get("failure")
        if failure:
            rep.failures[student] = failure
        rep.totals[student] = float(data.get("score", 0.0))
        per_q: dict[str, float] = defaultdict(float)
        for t in data.get("tests", []):
            qid, test = _split_name(str(t.get("name", "")))
            score, max_score = float(t.get("score", 0)), float(t.get("max_score", 0))
            per_q[qid] += score
            passed = t.get("status") == "passed" if "status" in t else score >= max_score - 1e-9
            tally = rep.tests.setdefault((qid, test), [0, 0])
            tally[0] += int(passed)
            tally[1] += 1
            for name in _mistakes_of(t):
                rep.mistakes[(qid, name)].add(student)
        for qid in _QUESTION_IDS:
            rep.scores[qid][student] = 0.0 if failure else per_q.get(qid, 0.0)
    return rep


def _histogram_png(values, max_points: float, title: str) -> bytes:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.2, 2.6), dpi=90)
    vals = np.asarray(list(values), float)
    bins = np.linspace(0, max(max_points, float(vals.max()) if vals.size else 0, 1e-9), 11)
    ax.hist(vals, bins=bins, color="#4a7ab5", edgecolor="white")
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("points")
    ax.set_ylabel("students")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return buf.getvalue()


def _read_roster(path: Path) -> list[dict]:
    with open(path, newline="", encoding="utf-8-sig") as fh:
        rows = list(csv.DictReader(fh))
    return [r for r in rows if (r.get("Student") or "").strip() and "Points Possible" not in (r.get("Student") or "")]


def canvas_rows(rep: ClassReport, assignment: str, roster: list[dict] | None = None,
                per_question: bool = False) -> list[list[str]]:
    """Rows of Canvas's gradebook import: header, "Points Possible", one per student.

    The assignment column carries the autograded total; ``per_question`` adds one column per
    question (named "<assignment> <Q>"), which Canvas creates as new assignments on import.
    """
    base_max = sum(_POINTS[q] for q in _QUESTION_IDS if q not in _EXTRA)
    cols = [assignment] + ([f"{assignment} {q}" for q in _QUESTION_IDS] if per_question else [])
    maxes = [points(base_max)] + ([points(_POINTS[q]) for q in _QUESTION_IDS] if per_question else [])
    rows = [list(CANVAS_COLUMNS) + cols, ["Points Possible", "", "", "", ""] + maxes]
    index = {}
    for r in roster or []:
        for key in ("SIS Login ID", "SIS User ID", "ID"):
            if (r.get(key) or "").strip():
                index.setdefault(r[key].strip(), r)
    for s in rep.students:
        r = index.get(s)
        ident = [r.get(c, "") for c in CANVAS_COLUMNS] if r else [s, "", "", s, ""]
        vals = [points(rep.totals[s])] + ([points(rep.scores[q][s]) for q in _QUESTION_IDS] if per_question else [])
        rows.append(ident + vals)
    return rows


def _submission_paths(graded: Path, students) -> list[tuple[str, str]]:
    """(student, the submission path its grading.json records, "" when none) for each student."""
    out = []
    for s in students:
        try:
            path = json.loads((graded / s / "grading.json").read_text(encoding="utf-8")).get("path") or ""
        except (OSError, ValueError, AttributeError):
            path = ""
        out.append((s, str(path)))
    return out


def write_report(graded: str | Path, out: str | Path, *, assignment: str = "HW4 autograded",
                 roster: str | Path | None = None, per_question: bool = False,
                 library_calls: dict[str, str] | None = None) -> dict:
    """Write the report files (see the module's docstring) into ``out``; return their paths by kind.

    library_calls: the names to look for -> what they do (``GradingConfig.library_names()``;
    None: the default list).
    """
    graded, out = Path(graded), private_folder(out)
    rep = build_report(load_results(graded))
    written = {}

    def csv_file(name: str, rows) -> Path:
        return write_atomic(out / name, csv_text(rows), mode=_PRIVATE)

    calls = find_in_class(_submission_paths(graded, rep.students), library_calls)
    written["library_calls"] = csv_file("library_calls.csv", [
        ["student", "library_function", "replaces", "kind", "in_function", "code", "where"]] + [
        [s, c.name, c.replaces, c.kind, c.function, c.code, c.where] for s in rep.students for c in calls[s][0]])
    written["tests"] = csv_file("tests.csv", [["question", "test", "passed", "results", "share_passed"]] + [
        [qid, test, passed, seen, f"{passed / seen:.3f}" if seen else ""]
        for (qid, test), (passed, seen) in sorted(rep.tests.items(), key=lambda kv: (_qorder(kv[0][0]), kv[0][1]))])
    mistakes = sorted(rep.mistakes.items(), key=lambda kv: (-len(kv[1]), _qorder(kv[0][0]), kv[0][1]))
    written["mistakes"] = csv_file("mistakes.csv", [["question", "mistake", "count", "students"]] + [
        [qid, name, len(studs), " ".join(sorted(studs))] for (qid, name), studs in mistakes])
    if (graded / "grades.csv").is_file():
        # Read and written again rather than copied: a gradebook written before its cells were
        # made safe gets them made safe here (already safe cells stay as they are).
        with open(graded / "grades.csv", newline="", encoding="utf-8", errors="replace") as fh:
            rows = list(csv.reader(fh))
    else:
        rows = [["student_id", "total", *_QUESTION_IDS]] + [
            [s, points(rep.totals[s])] + [points(rep.scores[q][s]) for q in _QUESTION_IDS] for s in rep.students]
    written["grades"] = csv_file("grades.csv", rows)
    written["canvas"] = csv_file("canvas.csv", canvas_rows(rep, assignment, _read_roster(Path(roster)) if roster
                                                           else None, per_question))
    # histograms
    pngs = {}
    for qid in _QUESTION_IDS:
        pngs[qid] = _histogram_png(rep.scores[qid].values(), _POINTS[qid], f"{qid}: {len(rep.students)} students")
    base_max = sum(_POINTS[q] for q in _QUESTION_IDS if q not in _EXTRA)
    pngs["total"] = _histogram_png(rep.totals.values(), base_max, "total (autograded)")
    for key, data in pngs.items():
        written[f"histogram_{key}"] = write_atomic(out / f"histogram_{key.replace('.', '_')}.png", data, mode=_PRIVATE)
    write_atomic(out / "report.html", _page(rep, pngs, mistakes, calls, mistake_examples(graded, mistakes)),
                 mode=_PRIVATE)
    written["html"] = out / "report.html"
    return written


def _qorder(qid: str) -> int:
    return _QUESTION_IDS.index(qid) if qid in _QUESTION_IDS else len(_QUESTION_IDS)


def _img(data: bytes, alt: str) -> str:
    return f"<img alt='{for_html(alt)}' src='data:image/png;base64,{base64.b64encode(data).decode()}'>"


def _page(rep: ClassReport, pngs: dict, mistakes, calls: dict, examples: dict | None = None) -> str:
    n = len(rep.students)
    e = for_html
    parts = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>Class report</title>",
             f"<style>{STYLE}</style></head><body><h1>Class report</h1>",
             f"<p>{n} graded results; {len(rep.failures)} could not be graded"
             + (f" ({e(', '.join(sorted(rep.failures)))})" if rep.failures else "") + ".</p>",
             "<h2>Scores</h2><table><tr><th>question</th><th>points</th><th>mean</th><th>median</th>"
             "<th>full marks</th><th>zero</th></tr>"]
    for qid in _QUESTION_IDS:
        v = np.array(list(rep.scores[qid].values()) or [0.0])
        full = int(np.sum(v >= _POINTS[qid] - 1e-9))
        zero = int(np.sum(v <= 1e-9))
        parts.append(f"<tr><td>{qid}</td><td>{_POINTS[qid]}</td><td>{v.mean():.2f}</td><td>{np.median(v):.2f}</td>"
                     f"<td>{full / max(n, 1):.0%}</td><td>{zero / max(n, 1):.0%}</td></tr>")
    parts.append("</table><div>" + "".join(_img(pngs[k], f"histogram {k}") for k in ["total", *_QUESTION_IDS])
                 + "</div>")
    parts.append("<h2>Share of the class that passed each test</h2><table><tr><th>question</th><th>test</th>"
                 "<th>passed</th><th>share</th></tr>")
    for (qid, test), (passed, seen) in sorted(rep.tests.items(), key=lambda kv: (_qorder(kv[0][0]), kv[0][1])):
        share = passed / seen if seen else 0.0
        cls = " class='flag'" if share < 0.5 else ""
        parts.append(f"<tr{cls}><td>{e(qid)}</td><td>{e(test)}</td><td>{passed} / {seen}</td><td>{share:.0%}</td></tr>")
    parts.append("</table><h2>Named mistakes</h2>")
    if mistakes:
        parts.append("<table><tr><th>question</th><th>mistake</th><th>students</th><th>who</th>"
                     "<th>an example (public data)</th></tr>")
        for (qid, name), studs in mistakes:
            example = (examples or {}).get((qid, name))
            parts.append(f"<tr><td>{e(qid)}</td><td>{e(name)}</td><td>{len(studs)}</td>"
                         f"<td>{e(', '.join(sorted(studs)))}</td><td>{_img(*example) if example else ''}</td></tr>")
        parts.append("</table>")
    else:
        parts.append("<p>No known mistake was named in the feedback.</p>")
    parts.append(_library_calls_section(calls))
    parts.append("</body></html>")
    return "\n".join(parts)


def _library_calls_section(calls: dict) -> str:
    """The page's list of library calls (student -> (LibraryCall list, notes)); student code escaped."""
    e = for_html
    with_calls = [s for s, (found, _) in calls.items() if found]
    parts = ["<h2 id='library-calls'>Library calls to look at</h2>",
             f"<p>Uses of library functions that do what the homework asks students to write, found in the "
             f"code without running it: {len(with_calls)} of {len(calls)} submissions. A reason to read the code, "
             "not a finding: no points were taken for them, and students are not shown this list.</p>"]
    if with_calls:
        parts.append("<table><tr><th>student</th><th>library function</th><th>does</th><th>use</th>"
                     "<th>in</th><th>code</th><th>where</th></tr>")
        for s in with_calls:
            for c in calls[s][0]:
                parts.append(f"<tr><td>{e(s)}</td><td>{e(c.name)}</td><td>{e(c.replaces)}</td><td>{e(c.kind)}</td>"
                             f"<td>{e(c.function)}</td><td><code>{e(c.code)}</code></td><td>{e(c.where)}</td></tr>")
        parts.append("</table>")
    unread = sorted(s for s, (_, notes) in calls.items() if notes)
    if unread:
        parts.append(f"<p>Code not read in full (a cell that does not parse, or the submission is not where its "
                     f"grading.json says): {e(', '.join(unread))}.</p>")
    return "".join(parts)
