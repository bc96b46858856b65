"""The PDF's cover page: the student's name and, for every question, whether it looks answered.

Nothing is run: the status comes from what the notebooks define (:mod:`handin.code_zip`) and
from whether a written answer cell still holds its placeholder.
"""

from __future__ import annotations

import html
import re
from dataclasses import dataclass
from pathlib import Path

from core.manifest import QUESTION_HEADING, QUESTIONS, Question

from .code_zip import NotebookInfo

__all__ = ["TITLE", "ANSWER_PLACEHOLDERS", "NO_NAME", "QuestionStatus", "question_status", "cover_html",
           "heading_id", "blank_answers"]

TITLE = "Homework 4: 3D Reconstruction"
ANSWER_PLACEHOLDERS = ("YOUR ANSWER HERE",)
NO_NAME = "(name not given)"


def heading_id(cell) -> str | None:
    """The question id when the cell's first non-blank line is a question heading."""
    if cell.cell_type != "markdown":
        return None
    first = next((line for line in cell.source.splitlines() if line.strip()), "")
    m = re.match(QUESTION_HEADING, first.strip())
    return m.group(1) if m else None


def _sections(nb) -> dict[str, list]:
    """Cells of each question: from its heading to the next question heading."""
    out: dict[str, list] = {}
    current = None
    for cell in nb.cells:
        qid = heading_id(cell)
        if qid:
            current = out.setdefault(qid, [])
        if current is not None:
            current.append(cell)
    return out


def _is_blank_answer(cell) -> bool:
    """A markdown cell that holds only the placeholder (or nothing): a written answer left blank."""
    if cell.cell_type != "markdown" or cell.get("attachments") or heading_id(cell):
        return False
    text = cell.source
    for p in ANSWER_PLACEHOLDERS:
        text = re.sub(re.escape(p), "", text, flags=re.IGNORECASE)
    return not re.sub(r"[\s*_#>-]", "", text)


def blank_answers(infos: list[NotebookInfo]) -> list[str]:
    """The questions (ids, manifest order) with a written answer left blank.

    A written answer is blank when its markdown cell still holds "YOUR ANSWER HERE" and nothing
    else, or is empty; this covers the written parts of coding questions (Q6's description of
    the method) as well as the written questions.
    """
    by_stem = {i.stem: i for i in infos if i.stem and i.nb is not None}
    out = []
    for q in QUESTIONS:
        info = by_stem.get(q.notebook)
        cells = _sections(info.nb).get(q.id, []) if info is not None else []
        if any(_is_blank_answer(c) for c in cells):
            out.append(q.id)
    return out


def _written_answer_given(cells) -> bool:
    """False when the section's answer cells still hold only the placeholder."""
    def is_answer_cell(c):
        meta = c.metadata.get("nbgrader", {})
        return c.cell_type == "markdown" and (meta.get("solution") or any(
            p.lower() in c.source.lower() for p in ANSWER_PLACEHOLDERS))

    answers = [c for c in cells if is_answer_cell(c)]
    if not answers:
        return True  # no answer cell to check: the student wrote straight under the heading
    for c in answers:
        text = c.source
        for p in ANSWER_PLACEHOLDERS:
            text = re.sub(re.escape(p), "", text, flags=re.IGNORECASE)
        if re.sub(r"[\s*_#>-]", "", text) or c.get("attachments"):
            return True
    return False


STATE_CLASS = {"answered": "answered", "partial": "partial", "not answered": "missing",
               "notebook missing": "missing"}


@dataclass(frozen=True)
class QuestionStatus:
    """question: the manifest entry; state: "answered", "partial", "not answered" or
    "notebook missing"; detail: what is missing, for the cover."""

    question: Question
    state: str
    detail: str = ""


def question_status(infos: list[NotebookInfo]) -> list[QuestionStatus]:
    """Status of every manifest question, from what the notebooks define (never run).

    A coding question is answered when all its functions are defined and none is a stub; a
    written question when its answer cell is no longer the untouched placeholder.
    """
    by_stem = {i.stem: i for i in infos if i.stem and i.nb is not None}
    blank = set(blank_answers(infos))
    out = []
    for q in QUESTIONS:
        info = by_stem.get(q.notebook)
        if info is None:
            out.append(QuestionStatus(q, "notebook missing", f"{q.notebook}.ipynb not included"))
        elif q.functions:
            missing = [f for f in q.functions if f not in info.implemented]
            state = ("answered" if not missing else
                     "partial" if len(missing) < len(q.functions) else "not answered")
            stubs = [f for f in missing if f in info.stubs]
            absent = [f for f in missing if f not in info.stubs]
            detail = "; ".join(([f"not defined: {', '.join(absent)}"] if absent else [])
                               + ([f"still a stub: {', '.join(stubs)}"] if stubs else []))
            if state == "answered" and q.id in blank:
                state, detail = "partial", "the written answer is blank"
            out.append(QuestionStatus(q, state, detail))
        else:
            cells = _sections(info.nb).get(q.id)
            if cells is None:
                out.append(QuestionStatus(q, "not answered", f"no '{q.id}' heading in {q.notebook}.ipynb"))
            else:
                given = _written_answer_given(cells) and q.id not in blank
                out.append(QuestionStatus(q, "answered" if given else "not answered",
                                          "" if given else "the written answer is blank"))
    return out


def cover_html(name: str, statuses: list[QuestionStatus], notebooks: list[Path], today: str) -> str:
    answered = [s.question.id for s in statuses if s.state == "answered"]
    blank = [s.question.id for s in statuses if s.detail == "the written answer is blank"]
    flagged = (f'<p class="hw4-blank">Blank written answers: {html.escape(", ".join(blank))} '
               "(the cell still says YOUR ANSWER HERE, or is empty)</p>") if blank else ""
    rows = "\n".join(
        f'<tr><td>{html.escape(s.question.id)}</td><td>{html.escape(s.question.title)}</td>'
        f'<td>{s.question.points}{" (extra)" if s.question.extra_credit else ""}</td>'
        f'<td class="hw4-status-{STATE_CLASS[s.state]}">{html.escape(s.state)}'
        f'{"<br><small>" + html.escape(s.detail) + "</small>" if s.detail else ""}</td></tr>'
        for s in statuses)
    listed = ", ".join(html.escape(p.name) for p in notebooks)
    return f"""
<section class="hw4-cover">
<h1>{html.escape(TITLE)}</h1>
<div class="hw4-subtitle">Written answers and code, for Gradescope</div>
<p class="hw4-name">Name: {html.escape(name)}</p>
<div class="hw4-date">Exported {html.escape(today)}</div>
<p class="hw4-answered">Answered: {html.escape(", ".join(answered) or "none")}
({len(answered)} of {len(statuses)})</p>
{flagged}
<table>
<thead><tr><th>Question</th><th>Title</th><th>Points</th><th>Status</th></tr></thead>
<tbody>
{rows}
</tbody>
</table>
<p class="hw4-help">Every question starts on a new page under its heading: in Gradescope, give each
question the pages from its heading to the next one. Notebooks: {listed}.</p>
</section>
"""
