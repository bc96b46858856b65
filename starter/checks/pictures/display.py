"""Showing a Picture in a notebook: the PNG with its alt text (HTML img alt, and the text below it).

Outside IPython the alt text is printed instead, so a script or a PDF export keeps the numbers.
"""

from __future__ import annotations

from starter.interactive import in_kernel

from .picture import Picture

__all__ = ["in_notebook", "show_picture"]


# Inside an IPython kernel (a notebook, Colab): the test the interactive matcher makes too.
in_notebook = in_kernel


def show_picture(picture: Picture) -> None:
    """Display ``picture`` (its PNG, alt text as img alt and caption), or print its alt text outside a notebook."""
    if not in_notebook():
        print(f"figure ({picture.question}): {picture.alt}")
        return
    from IPython.display import display

    display({"text/html": picture._repr_html_(), "image/png": picture.png, "text/plain": picture.alt}, raw=True)
