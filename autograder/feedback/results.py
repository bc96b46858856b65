"""The grading results: one model, one Gradescope serializer, a failure path, feedback and CSV.

``TestResult`` is one check, ``QuestionResult`` the checks of one manifest question,
``SubmissionResult`` a whole submission with the sandbox's isolation report.  Every output comes
from the model through one function each:

- ``SubmissionResult.to_gradescope()``: Gradescope's results.json (top-level score, output,
  visibility, stdout_visibility, extra_data; tests[] with name, number, score, max_score,
  status, output, visibility, and a check's ``extra_data.mistakes`` when its known mistakes were
  recorded: where the class report takes mistake names from);
- ``SubmissionResult.failed(reason)``: a valid result worth zero that says why, for when grading
  itself could not run (unreadable submission, broken sandbox);
- ``SubmissionResult.feedback_markdown()``: the readable report;
- ``csv_header()`` / ``SubmissionResult.csv_row()``: one gradebook line per student.

Feedback text passes through ``clean_feedback``, which removes Python tracebacks and bounds the
length: what a student reads never shows grader frames.  Hidden inputs must not be put in
feedback by the checks in the first place; checks marked ``visibility="hidden"`` are summarised
without their names or text in the student's report.

The model keeps plain text, which may quote the student (an exception's message, a file's name);
every writer here passes it through ``core.untrusted`` for its destination (Markdown for
feedback.md and results.json's outputs, a CSV cell for the gradebook), so none of it becomes
markup, a formula or a terminal escape.
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

from core.manifest import QUESTIONS, question
from core.text import points
from core.untrusted import for_csv_cell, for_markdown, visible

from .causes import said_once

__all__ = [
    "VISIBILITIES",
    "QuestionResult",
    "SubmissionResult",
    "TestResult",
    "autograded_question_ids",
    "clean_feedback",
    "csv_header",
    "write_csv",
]

VISIBILITIES = ("visible", "hidden", "after_due_date", "after_published")
# When a student sees a check of each visibility, earliest first: a check's feedback refers back
# only to checks shown no later (autograder.feedback.causes.said_once).
_SHOWN_ORDER = {v: k for k, v in enumerate(("visible", "after_due_date", "after_published", "hidden"))}
_FEEDBACK_LIMIT = 2000
_TOL = 1e-9


def clean_feedback(text: str, limit: int = _FEEDBACK_LIMIT) -> str:
    """``text`` without Python traceback frames, bounded to ``limit`` characters.

    A frame is a ``File "...", line N`` line with its indented source line; the
    ``Traceback (most recent call last):`` header goes too, the final ``Error: message`` stays.
    """
    if not isinstance(text, str):
        raise ValueError(f"text: expected str, got {type(text).__name__}")  # noqa: TRY004 - the kit's rule
    out: list[str] = []
    skip_source = False
    for line in text.splitlines():
        if line.startswith("Traceback (most recent call last)"):
            continue
        if re.match(r'\s*File ".*", line \d+', line):
            skip_source = True
            continue
        if skip_source and line.startswith("    "):
            continue  # the source line (and carets) printed under a frame
        skip_source = False
        out.append(line)
    cleaned = "\n".join(out).strip()
    return cleaned if len(cleaned) <= limit else cleaned[:limit] + " [...]"


def _mistake_codes(codes) -> tuple[str, ...]:
    """``codes`` as a tuple without repeats, each a key of the catalogue of known mistakes."""
    if isinstance(codes, str) or not isinstance(codes, (list, tuple)):
        raise ValueError(f"mistakes: expected a tuple of catalogue codes, got {codes!r}")
    if not codes:
        return ()
    from judging.mistakes import KNOWN_MISTAKES  # here: numpy and the catalogue only when there are codes

    unknown = [c for c in codes if not isinstance(c, str) or c not in KNOWN_MISTAKES]
    if unknown:
        raise ValueError(f"mistakes: expected codes of judging.mistakes.KNOWN_MISTAKES, got {unknown!r}")
    return tuple(dict.fromkeys(codes))


def _check_score(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{name}: expected a finite number, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class TestResult:
    """One check of one question.

    name: what was checked ("eightpoint: F maps points to their epipolar lines");
    score, max_score: points, 0 <= score <= max_score; passed: None means full marks;
    feedback: text for the student (cleaned of tracebacks, bounded); visibility: Gradescope's;
    mistakes: the codes (keys of ``judging.mistakes.KNOWN_MISTAKES``) of the known mistakes the
    grader's judging named in this check, as the grader recorded them; None when whoever made the
    result did not record them.  The class report counts these, never names read in ``feedback``,
    which may quote a student.
    """

    name: str
    score: float
    max_score: float
    passed: bool | None = None
    feedback: str = ""
    visibility: str = "visible"
    mistakes: tuple[str, ...] | None = None

    __test__ = False  # not a pytest test class despite its name

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError(f"name: expected a non-empty str, got {self.name!r}")
        score = _check_score(self.score, "score")
        max_score = _check_score(self.max_score, "max_score")
        if max_score < 0 or score < -_TOL or score > max_score + _TOL:
            raise ValueError(f"score: expected 0 <= score <= max_score = {max_score}, got {score}")
        if self.visibility not in VISIBILITIES:
            raise ValueError(f"visibility: expected one of {VISIBILITIES}, got {self.visibility!r}")
        object.__setattr__(self, "score", min(max(score, 0.0), max_score))
        object.__setattr__(self, "max_score", max_score)
        object.__setattr__(self, "feedback", clean_feedback(self.feedback))
        if self.mistakes is not None:
            object.__setattr__(self, "mistakes", _mistake_codes(self.mistakes))
        if self.passed is None:
            object.__setattr__(self, "passed", self.score >= self.max_score - _TOL)

    @classmethod
    def check(cls, name: str, ok: bool, points: float, feedback: str = "", **kw) -> TestResult:
        """All or nothing: ``points`` when ``ok``, else zero with ``feedback``."""
        return cls(name, points if ok else 0.0, points, bool(ok), "" if ok else feedback, **kw)


@dataclass(frozen=True)
class QuestionResult:
    """The checks of one manifest question, with the manifest's title and flags.

    notes: sentences about the question shown above its checks (e.g. "findM2 is not defined").
    """

    id: str
    title: str
    tests: tuple[TestResult, ...] = ()
    extra_credit: bool = False
    by_hand: bool = False
    notes: tuple[str, ...] = ()

    @classmethod
    def of(cls, qid: str, tests: Iterable[TestResult], notes: Iterable[str] = ()) -> QuestionResult:
        """A QuestionResult for the manifest question ``qid``; its checks must add up to its points.

        Raises
        ------
        ValueError
            When ``qid`` is unknown, or the checks' max_score total differs from the manifest's
            points (a grader bug: the question would be graded out of the wrong total).
        """
        q = question(qid)
        tests = tuple(tests)
        total = sum(t.max_score for t in tests)
        if not q.by_hand and abs(total - q.points) > 1e-6:
            raise ValueError(f"tests: expected max_score adding up to {q.points} for {qid}, got {total:g}")
        return cls(q.id, q.title, tests, q.extra_credit, q.by_hand, tuple(notes))

    @property
    def score(self) -> float:
        return sum(t.score for t in self.tests)

    @property
    def max_score(self) -> float:
        return sum(t.max_score for t in self.tests)


@dataclass(frozen=True)
class SubmissionResult:
    """A graded submission.

    questions: in manifest order; student_id: for the gradebook; isolation: the sandbox's
    ``Isolation.as_dict()``; notes: sentences about the submission as a whole (unreadable
    notebooks, syntax errors); failure: set when grading could not run (then the score is zero);
    execution_time: seconds; configuration: how it was graded (the grading run's stamp).

    pictures: the record of the unscored picture step when the grading run was asked for it
    (``GradingRun(..., pictures=True)``), else None: question -> the picture the grading worker
    drew of the public data, or the sentence why not, as the worker wrote it (read it with
    ``autograder.feedback.pictures.figures_of``, which checks it).  It is no part of the grade: never
    scored, compared, shown by ``repr`` nor written by ``to_dict`` (the pictures go to
    feedback.html and figures/, or to Gradescope's picture tests).
    """

    questions: tuple[QuestionResult, ...] = ()
    student_id: str | None = None
    isolation: dict | None = None
    notes: tuple[str, ...] = ()
    failure: str | None = None
    execution_time: float | None = None
    configuration: dict | None = None
    pictures: Mapping | None = field(default=None, compare=False, repr=False)

    @classmethod
    def failed(cls, reason: str, *, student_id: str | None = None, isolation: dict | None = None,
               execution_time: float | None = None, configuration: dict | None = None) -> SubmissionResult:
        """A zero for a submission that could not be graded, with ``reason`` for the student."""
        if not isinstance(reason, str) or not reason.strip():
            raise ValueError(f"reason: expected a non-empty str, got {reason!r}")
        return cls((), student_id, isolation, (), clean_feedback(reason), execution_time, configuration)

    @property
    def score(self) -> float:
        """Points earned, extra credit included; zero when grading failed."""
        return 0.0 if self.failure else sum(q.score for q in self.questions)

    @property
    def max_score(self) -> float:
        """Points of the autograded questions, extra credit excluded."""
        return sum(q.max_score for q in self.questions if not q.extra_credit)

    # -- the model as JSON (how a grading process hands its result to the grader) -------------

    def to_dict(self) -> dict:
        """Plain JSON data of the whole result (``from_dict`` reads it back)."""
        return {
            "questions": [{"id": q.id, "title": q.title, "extra_credit": q.extra_credit, "by_hand": q.by_hand,
                           "notes": list(q.notes), "tests": [asdict(t) for t in q.tests]} for q in self.questions],
            "student_id": self.student_id, "isolation": self.isolation, "notes": list(self.notes),
            "failure": self.failure, "execution_time": self.execution_time,
            "configuration": self.configuration,
        }

    @classmethod
    def from_dict(cls, data: dict, *, pictures: Mapping | None = None) -> SubmissionResult:
        """The result written by ``to_dict`` (every test re-validated), with the picture step's
        record ``pictures`` when it ran (written beside the result, never inside it)."""
        questions = tuple(
            QuestionResult(str(q["id"]), str(q["title"]), tuple(TestResult(**t) for t in q["tests"]),
                           bool(q["extra_credit"]), bool(q["by_hand"]), tuple(q["notes"]))
            for q in data["questions"])
        return cls(questions, data.get("student_id"), data.get("isolation"), tuple(data.get("notes", ())),
                   data.get("failure"), data.get("execution_time"), data.get("configuration"), pictures)

    # -- Gradescope -------------------------------------------------------------------------

    def to_gradescope(self, visibility: dict | None = None) -> dict:
        """The dict of Gradescope's results.json (all numbers finite, JSON-serialisable).

        ``visibility=None``: one test per check, with its points (what the CLI's results.json
        and its readers use).  A dict ``{"scores": V, "checks": V}`` (V one of ``VISIBILITIES``;
        a missing key takes the default ``{"scores": "visible", "checks": "after_published"}``)
        gives the layout for Gradescope itself: one test per question with its points (group
        "scores"), then one test per check with its feedback and no points (group "checks"; a
        check's own visibility wins when stricter), and a summary giving the base points and the
        extra credit apart.  The total score is the top-level "score" (extra credit included).
        """
        layout = None
        if visibility is not None:
            layout = {"scores": "visible", "checks": "after_published"}
            unknown = set(visibility) - set(layout)
            bad = {k: v for k, v in visibility.items() if v not in VISIBILITIES}
            if unknown or bad:
                raise ValueError(f"visibility: expected {{'scores'|'checks': one of {VISIBILITIES}}}, got {visibility!r}")
            layout.update(visibility)
        out: dict = {
            "score": round(self.score, 6),
            "output": self._summary_markdown(),
            "output_format": "md",
            # Each test's output is escaped for Markdown; without this Gradescope shows it as text.
            "test_output_format": "md",
            "visibility": "visible",
            "stdout_visibility": "hidden",  # the grader's log is for staff only
            "tests": [],
            "extra_data": {"isolation": self.isolation, "failure": self.failure,
                           "configuration": _public_configuration(self.configuration)},
        }
        if self.execution_time is not None:
            out["execution_time"] = round(float(self.execution_time), 3)
        if self.failure:
            return out
        if layout is None:
            for q in self.questions:
                said: dict = {}
                for k, t in enumerate(q.tests, start=1):
                    text = _check_output(q, k, t, said, _SHOWN_ORDER[t.visibility])
                    out["tests"].append({
                        "name": f"{q.id} {visible(t.name, newlines=False)}" + (" (extra credit)" if q.extra_credit else ""),
                        "number": f"{q.id[1:]}.{k}",
                        "score": round(t.score, 6),
                        "max_score": round(t.max_score, 6),
                        "status": "passed" if t.passed else "failed",
                        "output": text,
                        "visibility": t.visibility,
                        **_recorded_mistakes(t),
                    })
            return out
        order = _SHOWN_ORDER
        base = [q for q in self.questions if not q.extra_credit]
        extra = [q for q in self.questions if q.extra_credit]
        lines = [f"**Base points: {points(sum(q.score for q in base))} / {points(sum(q.max_score for q in base))}**"]
        if extra:
            lines.append(f"**Extra credit: {points(sum(q.score for q in extra))} / "
                         f"{points(sum(q.max_score for q in extra))}** ({', '.join(q.id for q in extra)}, "
                         f"added on top: score {points(self.score)})")
        if layout["checks"] != "visible":
            when = {"after_due_date": "after the due date", "after_published": "when the course staff publish the grades",
                    "hidden": "to the course staff only"}[layout["checks"]]
            lines.append(f"The feedback of each check is shown {when}.")
        if self.notes:
            lines += ["", "Notes on your files:"] + [f"- {for_markdown(n)}" for n in self.notes]
        out["output"] = "\n".join(lines)
        for q in self.questions:
            passed = sum(1 for t in q.tests if t.passed)
            out["tests"].append({
                "name": f"{q.id} {q.title}" + (" (extra credit)" if q.extra_credit else ""),
                "number": q.id[1:],
                "score": round(q.score, 6),
                "max_score": round(q.max_score, 6),
                "status": "passed" if q.score >= q.max_score - _TOL else "failed",
                "output": f"{passed} of {len(q.tests)} checks passed.",
                "visibility": layout["scores"],
            })
        for q in self.questions:
            said = {}
            for k, t in enumerate(q.tests, start=1):
                shown = max(layout["checks"], t.visibility, key=order.__getitem__)
                text = _check_output(q, k, t, said, order[shown])
                out["tests"].append({
                    "name": f"{q.id} check: {visible(t.name, newlines=False)} ({points(t.score)} / {points(t.max_score)})",
                    "number": f"{q.id[1:]}.{k}",
                    "status": "passed" if t.passed else "failed",
                    "output": text,
                    "visibility": shown,
                    **_recorded_mistakes(t),
                })
        return out

    def write_gradescope(self, path: str | Path) -> Path:
        """Write results.json to ``path`` atomically (a reader never sees half a file)."""
        path = Path(path)
        text = json.dumps(self.to_gradescope(), indent=2, allow_nan=False)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".results-", suffix=".json")
        try:
            with os.fdopen(fd, "w") as fh:
                fh.write(text)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return path

    # -- feedback ---------------------------------------------------------------------------

    def _summary_markdown(self) -> str:
        if self.failure:
            return (f"**The autograder could not grade this submission**, so it scores 0 for now.\n\n"
                    f"Reason: {for_markdown(self.failure)}\n\nPlease check your files and resubmit, or contact the course staff.")
        lines = [f"**Autograded total: {points(self.score)} / {points(self.max_score)}**"]
        if any(q.extra_credit for q in self.questions):
            extra = sum(q.score for q in self.questions if q.extra_credit)
            lines[0] += f" (including {points(extra)} extra credit)"
        if self.notes:
            lines += ["", "Notes on your files:"] + [f"- {for_markdown(n)}" for n in self.notes]
        return "\n".join(lines)

    def feedback_markdown(self, *, audience: str = "student") -> str:
        """A readable report.  ``audience="student"`` hides the names and texts of hidden checks;
        ``"staff"`` shows everything plus how the code was isolated."""
        if audience not in ("student", "staff"):
            raise ValueError(f"audience: expected 'student' or 'staff', got {audience!r}")
        title = "# Autograder feedback" + (f" for {_cell(self.student_id)}" if self.student_id else "")
        parts = [title, "", self._summary_markdown()]
        for q in ([] if self.failure else self.questions):
            head = f"## {q.id} {q.title}: {points(q.score)} / {points(q.max_score)}"
            parts += ["", head + (" (extra credit)" if q.extra_credit else "")]
            parts += [f"- {for_markdown(n)}" for n in q.notes]
            shown = [t for t in q.tests if audience == "staff" or t.visibility != "hidden"]
            hidden = [t for t in q.tests if t not in shown]
            if shown:
                parts += ["", "| Check | Score | Result |", "|---|---|---|"]
                parts += [f"| {_cell(t.name)} | {points(t.score)} / {points(t.max_score)} | "
                          f"{'passed' if t.passed else 'failed'} |" for t in shown]
            if hidden:
                hidden_score = f"{points(sum(t.score for t in hidden))} / {points(sum(t.max_score for t in hidden))}"
                parts += ["", f"{len(hidden)} hidden check(s): {hidden_score}"]
            details = [t for t in shown if t.feedback]
            said: dict = {}
            if details:
                parts += [""] + [f"- **{_cell(t.name)}**: {for_markdown(said_once(t.feedback, q.id, said))}"
                                 for t in details]
        if audience == "staff" and self.isolation:
            iso = self.isolation
            network = "cut" if iso.get("network_isolated") else "NOT cut"
            hidden_count = len(iso.get("hidden_paths") or ())
            line = f"Sandbox: {iso.get('level')}, uid {iso.get('uid')}, network {network}, {hidden_count} hidden paths."
            parts += ["", "---", line]
            parts += [f"- {for_markdown(n)}" for n in iso.get("notes") or ()]
        if audience == "staff" and self.configuration:
            c = self.configuration
            data = c.get("data") or {}
            parts += [f"Graded by grader {c.get('grader_version')} (kit {c.get('kit_version')}), secret "
                      f"{c.get('secret_fingerprint')}{' (DEVELOPMENT secret)' if c.get('dev_secret') else ''}, data: "
                      f"{'default' if data.get('default_data') else 'no default'}"
                      f"{' + official ' + str(data.get('official_data')) if data.get('official_data') else ''}, "
                      f"tests {(c.get('tests') or {}).get('digest')}, configuration {c.get('key')}."]
        return "\n".join(parts).rstrip() + "\n"

    # -- gradebook --------------------------------------------------------------------------

    def csv_row(self, question_ids: Sequence[str] | None = None) -> list[str]:
        """``[student_id, total, one score per question]`` in the order of ``csv_header``."""
        ids = list(question_ids) if question_ids is not None else autograded_question_ids()
        by_id = {q.id: q for q in self.questions}
        scores = [0.0 if self.failure or qid not in by_id else by_id[qid].score for qid in ids]
        return [self.student_id or "", points(self.score)] + [points(s) for s in scores]


def autograded_question_ids() -> list[str]:
    """Ids of the manifest's questions graded by the autograder, in manifest order."""
    return [q.id for q in QUESTIONS if not q.by_hand]


def csv_header(question_ids: Sequence[str] | None = None) -> list[str]:
    """``["student_id", "total", "Q2", ...]``."""
    ids = list(question_ids) if question_ids is not None else autograded_question_ids()
    return ["student_id", "total", *ids]


def write_csv(path: str | Path, results: Iterable[SubmissionResult],
              question_ids: Sequence[str] | None = None) -> Path:
    """Write one header line and one line per result."""
    path = Path(path)
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(csv_header(question_ids))
        for r in results:
            writer.writerow([for_csv_cell(c) for c in r.csv_row(question_ids)])
    return path


def _public_configuration(record: dict | None) -> dict | None:
    """The configuration record without the per-file digests (results.json stays small)."""
    if not record:
        return None
    out = dict(record)
    if isinstance(out.get("tests"), dict):
        out["tests"] = {k: v for k, v in out["tests"].items() if k != "files"}
    return out


def _recorded_mistakes(t: TestResult) -> dict:
    """A check's known mistakes for results.json: ``{"extra_data": {"mistakes": [codes]}}`` (a test's
    extra_data is Gradescope's "extra data to be stored"), or nothing when they were not recorded."""
    return {} if t.mistakes is None else {"extra_data": {"mistakes": list(t.mistakes)}}


def _cell(text: str) -> str:
    """A table cell or a title: one line of escaped Markdown (its "|" escaped too)."""
    return for_markdown(text, newlines=False)


def _check_output(q: QuestionResult, k: int, t: TestResult, said: dict, rank: int) -> str:
    """A check's output in results.json (Markdown): the question's notes with its first check, then
    its feedback, a likely mistake of the question's checks before it (``said``, updated) named
    without its hint again (``autograder.feedback.causes.said_once``; ``rank``: when the check is shown)."""
    feedback = said_once(t.feedback, q.id, said, rank)
    return "\n".join(for_markdown(x) for x in [*(q.notes if k == 1 else ()), feedback] if x)
