"""A student's offline feedback page: each question's verdict lines beside the picture of what
their code did on the public data.

``write(folder, result, figures)`` writes, beside ``results.json`` and ``feedback.md`` of a graded
folder (``<out>/<name>/``):

- ``feedback.html``: one page, no script and no external resource (a Content-Security-Policy
  allows only inline styles and ``data:`` images), every figure embedded as a ``data:`` URI
  with ``Picture.alt`` as its alt text; what the student reads in feedback.md, per question
  (hidden checks summarised without their names or text, as there);
- ``figures/<question>.png`` and ``figures/figures.json`` (question -> title, alt, measures and
  file, or the sentence why there is no figure): what the class report's examples are taken from.

``figures``: question -> ``Picture`` or "figure not drawn: ..." (``autograder.pictures.draw_all``).
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

from .pictures import finite_measures
from .results import QuestionResult, SubmissionResult

__all__ = ["CSP", "FIGURES", "PAGE", "figure_html", "page", "verdict_lines", "write"]

PAGE = "feedback.html"
FIGURES = "figures"
CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'"
_STYLE = """
body{font-family:system-ui,sans-serif;margin:1.5em;max-width:1200px;color:#222}
.q{display:flex;flex-wrap:wrap;gap:1.5em;align-items:flex-start;border-top:1px solid #ddd;padding:.8em 0}
.q figure{margin:0;flex:0 1 560px}.q figure img{max-width:100%;height:auto;border:1px solid #ccc}
.q .verdict{flex:1 1 320px;min-width:0}.passed{color:#1a6b2a}.failed{color:#a4161a}
.note{color:#555;font-style:italic}table{border-collapse:collapse}td{padding:1px 8px;border-bottom:1px solid #eee}
.fb{white-space:pre-wrap;margin:.2em 0 .6em 1.2em;color:#333}
"""


def _img(png: bytes, alt: str) -> str:
    return f"<img alt=\"{for_html(alt, newlines=False)}\" src=\"data:image/png;base64,{base64.b64encode(png).decode()}\">"


def figure_html(figure) -> str:
    """One figure as HTML: the ``Picture`` (image, title, measures) or the sentence why there is none."""
    if isinstance(figure, str):
        return f"<p class=\"note\">{for_html(figure)}</p>"
    rows = "".join(f"<tr><td>{for_html(k, newlines=False)}</td><td>{v:.4g}</td></tr>"
                   for k, v in finite_measures(figure).items())
    return (f"<figure>{_img(figure.png, figure.alt)}<figcaption>{for_html(figure.title)}"
            + (f"<table>{rows}</table>" if rows else "") + "</figcaption></figure>")


def verdict_lines(q: QuestionResult, *, feedback: bool = True) -> str:
    """The question's verdict lines as HTML: one per check a student may see (passed or failed,
    points, and with ``feedback`` its text), then the hidden checks summed up."""
    shown = [t for t in q.tests if t.visibility != "hidden"]
    hidden = [t for t in q.tests if t.visibility == "hidden"]
    parts = [f"<p class=\"note\">{for_html(n)}</p>" for n in q.notes]
    parts.append("<ul>")
    for t in shown:
        status = "passed" if t.passed else "failed"
        parts.append(f"<li><span class=\"{status}\">{status}</span>: {for_html(t.name, newlines=False)} "
                     f"({points(t.score)} / {points(t.max_score)})"
                     + (f"<div class=\"fb\">{for_html(t.feedback)}</div>" if feedback and t.feedback else "") + "</li>")
    if hidden:
        parts.append(f"<li>{len(hidden)} hidden check(s): {points(sum(t.score for t in hidden))} / "
                     f"{points(sum(t.max_score for t in hidden))}</li>")
    parts.append("</ul>")
    return "".join(parts)


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
    parts += [f"<p class=\"note\">{e(n)}</p>" for n in result.notes]
    parts.append("<p class=\"note\">The pictures show what your functions returned on the public data "
                 "(the data of the notebooks), not on the hidden tests' scenes; they are not graded.</p>")
    done = set()
    for q in () if result.failure else result.questions:
        done.add(q.id)
        head = f"{q.id} {q.title}: {points(q.score)} / {points(q.max_score)}" + (" (extra credit)" if q.extra_credit else "")
        figure = figure_html(figures[q.id]) if q.id in figures else ""
        parts.append(f"<section class=\"q\" id=\"{e(q.id)}\">{figure}<div class=\"verdict\"><h2>{e(head)}</h2>"
                     f"{verdict_lines(q)}</div></section>")
    for qid in figures:
        if qid not in done:
            parts.append(f"<section class=\"q\" id=\"{e(qid)}\">{figure_html(figures[qid])}<div class=\"verdict\">"
                         f"<h2>{e(qid)}</h2></div></section>")
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
