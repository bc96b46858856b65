"""A student's offline feedback page: each question's verdict lines beside the picture of what
their code did on the public data.

``write(folder, result, figures)`` writes, beside ``results.json`` and ``feedback.md`` of a graded
folder (``<out>/<name>/``):

- ``feedback.html``: one page, no script and no external resource (a Content-Security-Policy
  allows only inline styles and ``data:`` images), every figure embedded as a ``data:`` URI
  with ``Picture.alt`` as its alt text; read in a minute: the total and each question's score
  first (a table linking to the questions), then per question its failed checks in words
  (their feedback, as in feedback.md), the passed ones in one line each, its picture at the
  page's full width and the picture's measures named in words with their units
  (``autograder.feedback.pictures.measures_in_words``); hidden checks summarised without their names or
  text, as there; the notes about the submission's files and helpers folded at the end;
- ``figures/<question>.png`` and ``figures/figures.json`` (question -> title, alt, measures and
  file, or the sentence why there is no figure): what the class report's examples are taken from.

``figures``: question -> ``Picture`` or "figure not drawn: ..." (``autograder.feedback.pictures.figures_of``).
Every text passes ``core.untrusted.for_html``: a check's feedback and a "figure not drawn"
sentence may quote the student (an exception's message, a file name).
"""

from __future__ import annotations

import base64
import json
from collections.abc import Mapping
from pathlib import Path

from core.text import points, write_atomic
from core.untrusted import for_html

from .causes import said_once
from .pictures import finite_measures, measures_in_words
from .results import QuestionResult, SubmissionResult

__all__ = ["CSP", "FIGURES", "PAGE", "figure_html", "page", "verdict_lines", "write"]

PAGE = "feedback.html"
FIGURES = "figures"
CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'"
_STYLE = """
body{font-family:system-ui,sans-serif;margin:1.5em auto;max-width:1200px;padding:0 1em;color:#222;line-height:1.4}
.summary td,.summary th{padding:2px 10px;text-align:left;border-bottom:1px solid #eee}
.q{border-top:1px solid #ccc;padding:.8em 0}.q figure{margin:.6em 0}
.q figure img{width:100%;height:auto;border:1px solid #ccc}
.passed{color:#1a6b2a}.failed{color:#a4161a}
.note{color:#555;font-style:italic}table{border-collapse:collapse}td{padding:1px 8px;border-bottom:1px solid #eee}
.fb{white-space:pre-wrap;margin:.2em 0 .6em 1.2em;color:#333}figcaption{font-weight:600}
details.notes{margin-top:2em;border-top:1px solid #ccc;padding-top:.6em}
"""


def figure_html(figure, image: tuple[str, bytes] | None = None) -> str:
    """One figure as HTML: the ``Picture`` (image, title, its measures in words with their units)
    or the sentence why there is none.  ``image``: (MIME type, bytes) shown instead of the PNG (a
    smaller copy for Gradescope)."""
    if isinstance(figure, str):
        return f"<p class=\"note\">{for_html(figure)}</p>"
    rows = "".join(f"<tr><td>{for_html(words, newlines=False)}</td><td>{for_html(value, newlines=False)}</td></tr>"
                   for words, value in measures_in_words(figure))
    mime, data = image if image is not None else ("image/png", figure.png)
    img = (f"<img alt=\"{for_html(figure.alt, newlines=False)}\" "
           f"src=\"data:{mime};base64,{base64.b64encode(data).decode()}\">")
    return (f"<figure><figcaption>{for_html(figure.title)}</figcaption>{img}"
            + (f"<table>{rows}</table>" if rows else "") + "</figure>")


def verdict_lines(q: QuestionResult, *, feedback: bool = True, said: dict | None = None) -> str:
    """The question's verdict lines as HTML: its failed checks first (points, and with
    ``feedback`` what was measured and expected, in words), then the passed ones, one line each,
    then the hidden checks summed up.  ``said``: the likely mistakes named earlier on the page
    (``autograder.feedback.causes.said_once``): one cause is explained once."""
    shown = [t for t in q.tests if t.visibility != "hidden"]
    hidden = [t for t in q.tests if t.visibility == "hidden"]
    parts = [f"<p class=\"note\">{for_html(n)}</p>" for n in q.notes]
    parts.append("<ul>")
    for t in sorted(shown, key=lambda t: t.passed):   # failed first, each group in its order
        status = "passed" if t.passed else "failed"
        parts.append(f"<li><span class=\"{status}\">{status}</span>: {for_html(t.name, newlines=False)} "
                     f"({points(t.score)} / {points(t.max_score)})"
                     + (f"<div class=\"fb\">{for_html(said_once(t.feedback, q.id, said))}</div>"
                        if feedback and t.feedback and not t.passed
                        else "") + "</li>")
    if hidden:
        parts.append(f"<li>{len(hidden)} hidden check(s): {points(sum(t.score for t in hidden))} / "
                     f"{points(sum(t.max_score for t in hidden))}</li>")
    parts.append("</ul>")
    return "".join(parts)


def _summary(result: SubmissionResult) -> str:
    """The table of every question's score, each linking to its section."""
    e = for_html
    rows = []
    for q in result.questions:
        failed = sum(not t.passed for t in q.tests)
        state = "full marks" if q.score >= q.max_score - 1e-9 else f"{failed} check(s) failed"
        rows.append(f"<tr><td><a href=\"#{e(q.id)}\">{e(q.id)}</a></td><td>{e(q.title)}</td>"
                    f"<td>{points(q.score)} / {points(q.max_score)}</td><td>{e(state)}</td></tr>")
    return ("<table class=\"summary\"><tr><th>question</th><th></th><th>points</th><th></th></tr>"
            + "".join(rows) + "</table>")


def page(result: SubmissionResult, figures: Mapping) -> str:
    """The page's HTML (see the module's docstring)."""
    e = for_html
    who = f" for {e(result.student_id, newlines=False)}" if result.student_id else ""
    parts = ["<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">",
             f"<meta http-equiv=\"Content-Security-Policy\" content=\"{CSP}\">",
             f"<title>Autograder feedback{who}</title><style>{_STYLE}</style></head><body>",
             f"<h1>Autograder feedback{who}</h1>"]
    if result.failure:
        parts.append(f"<p><strong>The autograder could not grade this submission</strong>: {e(result.failure)}</p>")
    else:
        parts.append(f"<p><strong>Autograded total: {points(result.score)} / {points(result.max_score)}</strong>"
                     + (" (extra credit included)" if any(q.extra_credit for q in result.questions) else "") + "</p>")
    if not result.failure:
        parts.append(_summary(result))
    parts.append("<p class=\"note\">The pictures show what your functions returned on the public data "
                 "(the data of the notebooks), not on the hidden tests' scenes; they are not graded.</p>")
    done, said = set(), {}
    for q in () if result.failure else result.questions:
        done.add(q.id)
        head = f"{q.id} {q.title}: {points(q.score)} / {points(q.max_score)}" + (" (extra credit)" if q.extra_credit else "")
        figure = figure_html(figures[q.id]) if q.id in figures else ""
        parts.append(f"<section class=\"q\" id=\"{e(q.id)}\"><h2>{e(head)}</h2>{verdict_lines(q, said=said)}{figure}"
                     "</section>")
    for qid in figures:
        if qid not in done:
            parts.append(f"<section class=\"q\" id=\"{e(qid)}\"><h2>{e(qid)}</h2>{figure_html(figures[qid])}</section>")
    if result.notes:
        # About the files and helpers of the submission: useful, and not what a student reads first.
        parts.append(f"<details class=\"notes\"><summary>Notes about your files and helpers ({len(result.notes)})"
                     "</summary>" + "".join(f"<p class=\"note\">{e(n)}</p>" for n in result.notes) + "</details>")
    parts.append("</body></html>")
    return "\n".join(parts)


def _file(qid: str) -> str:
    return qid.replace(".", "_") + ".png"


def write(folder: str | Path, result: SubmissionResult, figures: Mapping, *, mode: int = 0o644) -> Path:
    """Write ``feedback.html`` and ``figures/`` into ``folder`` (see the module's docstring); the page's path."""
    folder = Path(folder)
    figures = dict(figures or {})
    store = folder / FIGURES
    store.mkdir(parents=True, exist_ok=True)
    index = {}
    for qid, figure in figures.items():
        if isinstance(figure, str):
            index[qid] = {"error": figure}
            continue
        write_atomic(store / _file(qid), figure.png, mode=mode)
        index[qid] = {"title": figure.title, "alt": figure.alt, "measures": finite_measures(figure), "file": _file(qid)}
    write_atomic(store / "figures.json", json.dumps(index, indent=1, allow_nan=False), mode=mode)
    return write_atomic(folder / PAGE, page(result, figures), mode=mode)
