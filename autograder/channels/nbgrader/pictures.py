"""The pictures in nbgrader's feedback: the outputs of one hidden-check cell, the question's
verdict and then the figure of what the student's functions returned on the public data.

``nbgrader generate_feedback`` converts the autograded notebooks with its "feedback" template,
which extends nbconvert's classic HTML template.  That template shows a ``display_data`` output's
``image/png`` as ``<img src="data:image/png;base64,...">`` and takes the img's ``alt`` from the
output's metadata ``{"image/png": {"alt": ...}}``, escaped as an attribute value.  So a figure is
one such output, its ``text/plain`` the same alt text (what a viewer without images shows); a
figure that was not drawn is its sentence ("figure not drawn: ...") at the end of the verdict's
text instead.

What may quote the student stays data: the stream text passes ``core.untrusted.for_terminal``
as before, and the alt text (``figures_of`` guarantees a non-empty str of bounded length, not
its characters) passes ``core.untrusted.visible`` on one line.  It is not HTML-escaped here: the
template escapes it, and escaping it twice would show "&amp;" to the student.
"""

from __future__ import annotations

import base64

from core.untrusted import for_terminal, visible

__all__ = ["LEAD", "cell_outputs"]

LEAD = "The picture below (not graded) shows what your functions returned on the public data"


def cell_outputs(verdict: str, figure=None) -> list:
    """The outputs of a hidden-check cell: ``verdict`` as a stream output, then ``figure`` (a
    ``Picture``, the sentence why there is none, or None: nothing more)."""
    import nbformat

    lines = [verdict]
    if isinstance(figure, str):
        lines.append(figure)
    elif figure is not None:
        lines.append(f"{LEAD}: {figure.title}")
    # A stream output is shown as a terminal would (nbconvert turns ANSI escapes into markup);
    # each part escaped and bounded on its own, so a long verdict never cuts the figure's sentence.
    text = "\n".join(for_terminal(line) for line in lines)
    outputs = [nbformat.v4.new_output("stream", name="stdout", text=text + "\n")]
    if figure is not None and not isinstance(figure, str):
        alt = visible(figure.alt, newlines=False)
        outputs.append(nbformat.v4.new_output(
            "display_data", data={"image/png": base64.b64encode(figure.png).decode("ascii"), "text/plain": alt},
            metadata={"image/png": {"alt": alt}}))
    return outputs
