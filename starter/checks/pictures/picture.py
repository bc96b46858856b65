"""What a figure of the feedback is: :class:`Picture`, and the one way a matplotlib figure becomes one.

A Picture carries its PNG, a text equivalent (``alt``) written from the numbers measured on what
is drawn, and those numbers (``measures``) for programs and tests.  Figures are drawn with the
Agg backend only (no display needed), and closed once rendered.
"""

from __future__ import annotations

import io
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

__all__ = ["Picture", "figure", "measure_text", "to_picture"]


@dataclass(frozen=True)
class Picture:
    """One feedback figure.

    question : "Q2", "Q3.1", "Q3.2", "Q3.3", "Q4.1", "Q4.2", "Q5" or "Q6".
    title : one line naming what is drawn.
    png : the figure, PNG bytes.
    alt : its text equivalent: what is drawn and the numbers measured on it.
    measures : name -> number measured on what is drawn (pixels, pixels^2 or scene units, as the
        name says); read-only.
    """

    question: str
    title: str
    png: bytes
    alt: str
    measures: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "measures", MappingProxyType({str(k): float(v) for k, v in self.measures.items()}))

    def _repr_png_(self) -> bytes:
        return self.png

    def _repr_html_(self) -> str:
        import base64
        import html

        data = base64.b64encode(self.png).decode("ascii")
        return (f"<figure><img src='data:image/png;base64,{data}' alt='{html.escape(self.alt, quote=True)}'>"
                f"<figcaption>{html.escape(self.alt)}</figcaption></figure>")


def figure(ncols: int = 1, nrows: int = 1, size=(5.0, 4.0)):
    """(fig, axes) of a new Agg figure, ``axes`` always a flat list; ``size`` per panel, inches."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(size[0] * ncols, size[1] * nrows), dpi=90)
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel().tolist()
    return fig, axes


def to_picture(question: str, title: str, fig, alt: str, measures: Mapping[str, float]) -> Picture:
    """Render ``fig`` (a matplotlib Figure) to PNG and wrap it with its text equivalent."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    fig.suptitle(title, fontsize=10)
    # tight_layout alone fits the panels, their labels and the title: cropping to the drawn ink as
    # well (bbox_inches="tight") cost one more layout pass, an eighth of a picture's time.
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return Picture(question, title, buf.getvalue(), alt, measures)


def measure_text(x: float, unit: str = "") -> str:
    """A measured number for the alt text: 3 significant digits, "not finite" for NaN or inf."""
    x = float(x)
    if x != x or x in (float("inf"), float("-inf")):
        return "not finite"
    return f"{x:.3g}" + (f" {unit}" if unit else "")
