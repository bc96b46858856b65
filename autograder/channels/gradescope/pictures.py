"""The pictures in Gradescope's results.json: one unscored test per question, its output HTML.

Gradescope's results format (its "Autograder Specifications", section "Output String
Formatting"; gradescope/autograder_samples pull request 92) lets each test say how its
``output`` is shown: ``output_format`` "text" (the default for tests), "simple_format", "md",
"ansi" or "html", which Gradescope renders after sanitising it ("you may not be able to use all
html elements").  So a question's picture is a test of its own with ``output_format`` "html": an
``<img>`` whose ``src`` is the PNG as a ``data:`` URI and whose ``alt`` is ``Picture.alt``, its
title and measures (in words), and the question's verdict lines (check names, passed or failed,
points; their feedback is in the checks' own tests).  The image is a smaller copy of the PNG
(``compact``: at most ``MAX_WIDTH`` pixels wide, as JPEG or as a PNG of few colours, whichever is
smaller), so that one student's results.json stays within a few hundred kB.  Whether the sanitiser keeps ``data:`` images is not
documented: when it does not, the student still reads the title, the alt text, the measures and
the verdicts.  The test has no score and no max_score (it counts for nothing); its status is
its question's (passed at full marks), so that Gradescope colours it as the checks beside it.

Visibility: a picture is never shown earlier than any test of its question in the same
results.json (the strictest of their visibilities: ``visible`` < ``after_due_date`` <
``after_published`` < ``hidden``), so the bundle's ``--visibility`` settings and a hidden check
keep the picture back with the verdicts it stands beside.  A question without any test there
gets no picture.
"""

from __future__ import annotations

import base64
import io
import sys
import traceback
from collections.abc import Mapping

from core.untrusted import visible  # a test name is shown as text (name_format "text")

from autograder.feedback.page import figure_html, verdict_lines
from autograder.feedback.pictures import figures_of
from autograder.feedback.results import SubmissionResult

__all__ = ["MAX_PNG_BYTES", "MAX_WIDTH", "STRICTNESS", "add_pictures", "compact", "picture_tests"]

STRICTNESS = ("visible", "after_due_date", "after_published", "hidden")
MAX_PNG_BYTES = 1_500_000   # a larger figure is named, not embedded (results.json stays small)
MAX_WIDTH = 800             # pixels of a picture's copy in results.json


def compact(png: bytes) -> tuple[str, bytes]:
    """(MIME type, bytes) of a smaller copy of ``png`` for results.json: at most ``MAX_WIDTH``
    pixels wide, JPEG (photographs: the temple's images) or a PNG of 64 colours (plots), whichever
    is smaller; the PNG itself when it is already smaller or cannot be read."""
    try:
        from PIL import Image

        image = Image.open(io.BytesIO(png)).convert("RGB")
        if image.width > MAX_WIDTH:
            image = image.resize((MAX_WIDTH, max(1, round(image.height * MAX_WIDTH / image.width))), Image.LANCZOS)
        jpeg, few = io.BytesIO(), io.BytesIO()
        image.save(jpeg, "JPEG", quality=70, optimize=True)
        image.quantize(colors=64).save(few, "PNG", optimize=True)
    except Exception:  # noqa: BLE001 - a copy that cannot be made: the PNG as it is
        return "image/png", png
    return min((("image/png", png), ("image/jpeg", jpeg.getvalue()), ("image/png", few.getvalue())),
               key=lambda it: len(it[1]))


def _strictest(visibilities) -> str:
    return max(visibilities, key=STRICTNESS.index)


def picture_tests(data: dict, result: SubmissionResult, figures: Mapping) -> list[tuple[int, dict]]:
    """(index after which to insert, test) for each question of ``result`` with a figure and with
    tests in ``data["tests"]`` (see the module's docstring)."""
    tests = data.get("tests") or []
    out = []
    for q in result.questions:
        if q.id not in figures:
            continue
        mine = [k for k, t in enumerate(tests) if str(t.get("name", "")).startswith(q.id + " ")]
        if not mine:
            continue
        figure = figures[q.id]
        if not isinstance(figure, str) and len(figure.png) > MAX_PNG_BYTES:
            figure = f"figure not shown here: {len(base64.b64encode(figure.png)) // 1000} kB is too large"
        title = "figure not drawn" if isinstance(figure, str) else figure.title
        out.append((mine[-1], {
            "name": f"{q.id} picture: {visible(title, 200, newlines=False)}",
            "number": f"{q.id[1:]}.0",
            "status": "passed" if q.score >= q.max_score - 1e-9 else "failed",  # the question's, for its colour
            "output": ("<p>What your functions returned on the public data (not graded):</p>"
                       + figure_html(figure, None if isinstance(figure, str) else compact(figure.png))
                       + verdict_lines(q, feedback=False)),
            "output_format": "html",
            "visibility": _strictest(str(tests[k].get("visibility", "visible")) for k in mine),
        }))
    return out


def add_pictures(data: dict, result: SubmissionResult, raw) -> dict:
    """``data`` (results.json's dict) with the picture tests of ``raw`` (the picture step's record a
    result of the grading run carries, ``SubmissionResult.pictures``: decoded, checked and drawn here) inserted after each question's tests.
    Never raises: a failure of this step is printed for staff (Gradescope's stdout) and the
    results stay as they were."""
    if not raw or result.failure:
        return data
    try:
        extra = picture_tests(data, result, figures_of(raw))
        for index, test in sorted(extra, key=lambda it: -it[0]):
            data["tests"].insert(index + 1, test)
    except Exception:  # noqa: BLE001 - pictures never cost the results
        traceback.print_exc(file=sys.stdout)
    return data
