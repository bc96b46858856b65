"""Epipolar lines and matches, picked by clicking in a notebook or listed for the PDF.

``displayEpipolarF(I1, I2, F)`` shows the epipolar line ``l = F x1`` in image 2 of every point
picked in image 1; ``epipolarMatchGUI(I1, I2, F, match_fn)`` also calls the student's
``epipolarCorrespondence`` and draws the match it returns.

Two forms, one figure
---------------------
Static (``points=`` given, at least 5 recommended): a matplotlib figure of image 1 with the
points and image 2 with their lines (and matches), one colour per pair.  It is displayed as a
plain PNG, which is what nbconvert and the PDF keep.

Interactive (``points`` omitted, inside Jupyter or Colab): click in image 1 of a plotly
``FigureWidget`` (needs the ``anywidget`` package with plotly 6 or later), or type the pixel
in the x1/y1 boxes and press the button, which always works with plain ipywidgets.  Under the
widget the same static PNG is displayed and redrawn after every pick, so the saved notebook,
and its PDF, carry the picks made by hand.

Conventions: a pixel is (x, y) = (column, row), with (0, 0) the centre of the top-left pixel;
``F`` maps points of image 1 to lines of image 2 (``x2^T F x1 = 0``).  Images are uint8, or
float in [0, 1], of shape (H, W) or (H, W, 3).  The pure functions (:func:`epipolar_line`,
:func:`epipolar_line_endpoints`) and :class:`EpipolarSession` need no browser.
"""

from __future__ import annotations

import base64
import html
import io
import sys
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from core.geometry import epipolar_distances
from core.validate import DegenerateInputError, as_finite_scalar, as_image, as_matrix, as_points, as_positive_scalar

__all__ = [
    "epipolar_line",
    "epipolar_line_endpoints",
    "pair_colors",
    "EpipolarPick",
    "EpipolarSession",
    "EpipolarApp",
    "displayEpipolarF",
    "epipolarMatchGUI",
]


# --------------------------------------------------------------------------------------------
# geometry

def epipolar_line(F, x1, y1) -> np.ndarray:
    """The epipolar line in image 2 of pixel (x1, y1) of image 1.

    Parameters
    ----------
    F : array_like, shape (3, 3)
        Fundamental matrix, ``x2^T F x1 = 0``.
    x1, y1 : float
        Column and row of the point in image 1.

    Returns
    -------
    numpy.ndarray, shape (3,)
        ``l = (a, b, c)`` proportional to ``F @ (x1, y1, 1)`` and scaled so that
        ``a**2 + b**2 == 1``; then ``a*x + b*y + c`` is the signed distance in pixels of (x, y)
        from the line.

    Raises
    ------
    DegenerateInputError
        When ``F @ (x1, y1, 1)`` has no direction (a = b = 0): (x1, y1) is the epipole of
        image 1, whose epipolar "line" is undefined.
    """
    F = as_matrix(F, "F", (3, 3))
    x = np.array([as_finite_scalar(x1, "x1"), as_finite_scalar(y1, "y1"), 1.0])
    line = F @ x
    norm = np.hypot(line[0], line[1])
    # relative test: F is only known up to scale
    if norm <= 1e-12 * max(np.abs(F).max() * np.abs(x).max(), 1e-300):
        raise DegenerateInputError(
            f"(x1, y1) = ({x[0]:g}, {x[1]:g}) is the epipole of image 1 (F x1 has a = b = 0): "
            f"it has no epipolar line")
    return line / norm


def epipolar_line_endpoints(F, x1, y1, width, height):
    """The part of the epipolar line of (x1, y1) that crosses image 2.

    Parameters
    ----------
    F : array_like, shape (3, 3)
        Fundamental matrix, ``x2^T F x1 = 0``.
    x1, y1 : float
        The point in image 1 (column, row).
    width, height : int
        Size of image 2 in pixels.  The line is clipped to the rectangle of pixel centres,
        ``0 <= x <= width - 1`` and ``0 <= y <= height - 1``.

    Returns
    -------
    numpy.ndarray of shape (2, 2), or None
        ``[[xa, ya], [xb, yb]]``, the two ends of the visible segment, both on the line, or
        None when the line misses the image (or only touches a corner).

    Raises
    ------
    ValueError
        For a malformed argument; DegenerateInputError when (x1, y1) is the epipole.
    """
    W = as_positive_scalar(width, "width")
    H = as_positive_scalar(height, "height")
    a, b, c = epipolar_line(F, x1, y1)
    xmax, ymax = W - 1.0, H - 1.0
    tol = 1e-9 * max(xmax, ymax, 1.0)
    hits = []
    if abs(b) > 1e-15:
        for x in (0.0, xmax):
            y = -(a * x + c) / b
            if -tol <= y <= ymax + tol:
                hits.append((x, min(max(y, 0.0), ymax)))
    if abs(a) > 1e-15:
        for y in (0.0, ymax):
            x = -(b * y + c) / a
            if -tol <= x <= xmax + tol:
                hits.append((min(max(x, 0.0), xmax), y))
    if len(hits) < 2:
        return None
    pts = np.array(hits)
    # a line through a corner meets two borders there: keep the two hits farthest apart
    d = np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=2)
    i, j = np.unravel_index(np.argmax(d), d.shape)
    if d[i, j] <= tol:
        return None
    return np.array([pts[i], pts[j]])


def pair_colors(n: int) -> list[str]:
    """``n`` distinct hex colours, one per picked pair (tab10, then tab20, then a turbo ramp)."""
    from matplotlib import colormaps
    from matplotlib.colors import to_hex

    if n <= 10:
        return [to_hex(colormaps["tab10"](i)) for i in range(n)]
    if n <= 20:
        return [to_hex(colormaps["tab20"](i)) for i in range(n)]
    return [to_hex(colormaps["turbo"](i / (n - 1))) for i in range(n)]


# --------------------------------------------------------------------------------------------
# the state of a picking session, independent of any front end


@dataclass(frozen=True, eq=False)
class EpipolarPick:
    """One point picked in image 1 and what it gives in image 2.

    Attributes
    ----------
    x1, y1 : int
        The picked pixel of image 1 (column, row), rounded to the nearest pixel.
    line : numpy.ndarray, shape (3,)
        Its epipolar line in image 2, scaled so that ``line @ (x, y, 1)`` is a distance in px.
    endpoints : numpy.ndarray of shape (2, 2), or None
        The visible segment of the line, ``[[xa, ya], [xb, yb]]``; None if it misses image 2.
    match : (float, float) or None
        What ``match_fn`` returned, (x2, y2); None without a matcher.
    distance : float or None
        Distance of the match from the line, in pixels.
    warning : str or None
        Set when the match is far from the line or outside image 2.
    """

    x1: int
    y1: int
    line: np.ndarray
    endpoints: np.ndarray | None
    match: tuple[float, float] | None = None
    distance: float | None = None
    warning: str | None = None

    def describe(self) -> str:
        """One line of plain text about this pick."""
        a, b, c = self.line
        text = f"(x1, y1) = ({self.x1}, {self.y1}): line {a:+.4f} x {b:+.4f} y {c:+.2f} = 0"
        if self.endpoints is None:
            text += ", outside image 2"
        else:
            (xa, ya), (xb, yb) = self.endpoints
            text += f" from ({xa:.1f}, {ya:.1f}) to ({xb:.1f}, {yb:.1f})"
        if self.match is not None:
            text += (f"; match (x2, y2) = ({self.match[0]:.1f}, {self.match[1]:.1f}), "
                     f"{self.distance:.2f} px from the line")
        if self.warning:
            text += f". WARNING: {self.warning}"
        return text


class EpipolarSession:
    """Picks made in image 1, their epipolar lines in image 2 and, optionally, their matches.

    Parameters
    ----------
    I1, I2 : array_like, shape (H, W) or (H, W, 3)
        The two images, uint8 or float in [0, 1].
    F : array_like, shape (3, 3)
        Fundamental matrix, ``x2^T F x1 = 0``.
    match_fn : callable, optional
        ``match_fn(I1, I2, F, x1, y1) -> (x2, y2)``, the student's ``epipolarCorrespondence``.
        It receives the images and F exactly as passed here and integer pixel coordinates.
    far_threshold : float
        A match farther than this from the epipolar line (pixels) gets a warning.

    Attributes
    ----------
    picks : list of EpipolarPick
        In the order they were made.
    """

    def __init__(self, I1, I2, F, match_fn: Callable | None = None, *,
                 far_threshold: float = 2.0):
        self.image1 = as_image(I1, "I1")
        self.image2 = as_image(I2, "I2")
        self.F = as_matrix(F, "F", (3, 3))
        if match_fn is not None and not callable(match_fn):
            raise ValueError(f"match_fn: expected a function (im1, im2, F, x1, y1) -> (x2, y2), "
                             f"got {type(match_fn).__name__}")
        self._inputs = (I1, I2, F)
        self.match_fn = match_fn
        self.far_threshold = as_positive_scalar(far_threshold, "far_threshold")
        self.picks: list[EpipolarPick] = []
        #: the EpipolarApp showing this session, when there is one
        self.app = None

    def __repr__(self) -> str:
        kind = "matches" if self.match_fn is not None else "lines"
        return f"<EpipolarSession: {len(self.picks)} {kind}>"

    @property
    def size1(self) -> tuple[int, int]:
        """(width, height) of image 1."""
        return self.image1.shape[1], self.image1.shape[0]

    @property
    def size2(self) -> tuple[int, int]:
        """(width, height) of image 2."""
        return self.image2.shape[1], self.image2.shape[0]

    def pick(self, x1, y1) -> EpipolarPick:
        """Pick pixel (x1, y1) of image 1: compute its line, call the matcher, record it.

        Raises
        ------
        ValueError
            When (x1, y1) is not a finite pixel inside image 1, or ``match_fn`` returns
            something other than two finite numbers.  Whatever ``match_fn`` raises passes
            through unchanged.
        """
        x = as_finite_scalar(x1, "x1")
        y = as_finite_scalar(y1, "y1")
        w1, h1 = self.size1
        if not (-0.5 <= x < w1 - 0.5):
            raise ValueError(f"x1: expected a column of image 1, in [0, {w1 - 1}], got {x:g}")
        if not (-0.5 <= y < h1 - 0.5):
            raise ValueError(f"y1: expected a row of image 1, in [0, {h1 - 1}], got {y:g}")
        # students index windows with these: whole pixels, as the original helper gave them
        xi = min(max(int(np.floor(x + 0.5)), 0), w1 - 1)
        yi = min(max(int(np.floor(y + 0.5)), 0), h1 - 1)
        line = epipolar_line(self.F, xi, yi)
        w2, h2 = self.size2
        ends = epipolar_line_endpoints(self.F, xi, yi, w2, h2)
        match = distance = warning = None
        if self.match_fn is not None:
            I1, I2, F = self._inputs
            result = self.match_fn(I1, I2, F, xi, yi)
            try:
                m = np.asarray(result, dtype=float).ravel()
            except (TypeError, ValueError):
                m = np.array([])
            if m.size != 2 or not np.all(np.isfinite(m)):
                raise ValueError(f"match_fn: expected it to return (x2, y2), two finite numbers, "
                                 f"got {result!r}")
            match = (float(m[0]), float(m[1]))
            distance = float(epipolar_distances(self.F, [(xi, yi)], [match])[0])
            if distance > self.far_threshold:
                warning = (f"the match ({match[0]:.1f}, {match[1]:.1f}) is {distance:.1f} px from "
                           f"the epipolar line (more than {self.far_threshold:g} px): "
                           f"the correspondence should lie on the line")
            elif not (-0.5 <= match[0] < w2 - 0.5 and -0.5 <= match[1] < h2 - 0.5):
                warning = (f"the match ({match[0]:.1f}, {match[1]:.1f}) is outside image 2 "
                           f"({w2} x {h2})")
        elif ends is None:
            warning = "the epipolar line does not cross image 2"
        record = EpipolarPick(xi, yi, line, ends, match, distance, warning)
        self.picks.append(record)
        return record

    def clear(self) -> None:
        """Forget every pick."""
        self.picks.clear()

    def points(self) -> np.ndarray:
        """The picked pixels of image 1, shape (K, 2), rows (x1, y1)."""
        return np.array([[p.x1, p.y1] for p in self.picks], dtype=float).reshape(-1, 2)

    def matches(self) -> np.ndarray:
        """The matches in image 2, shape (K, 2); rows of NaN where there was no matcher."""
        rows = [p.match if p.match is not None else (np.nan, np.nan) for p in self.picks]
        return np.array(rows, dtype=float).reshape(-1, 2)

    def figure(self, *, width_inches: float = 12.0, title: str | None = None):
        """The static figure of the current picks: a ``matplotlib.figure.Figure``.

        Left, image 1 with the picked points; right, image 2 with their epipolar lines and,
        with a matcher, the matches.  Pair k has the same colour on both sides.  The figure is
        not registered with pyplot (display it, or save it with ``savefig``).
        """
        from matplotlib.figure import Figure

        h = max(self.image1.shape[0] / self.image1.shape[1],
                self.image2.shape[0] / self.image2.shape[1])
        fig = Figure(figsize=(width_inches, width_inches / 2 * h + 0.9))
        ax1, ax2 = fig.subplots(1, 2)
        _show_image(ax1, self.image1)
        _show_image(ax2, self.image2)
        colors = pair_colors(len(self.picks))
        matcher = self.match_fn is not None
        for p, color in zip(self.picks, colors):
            ax1.plot(p.x1, p.y1, "o", markersize=7, markerfacecolor="none",
                     markeredgecolor=color, markeredgewidth=2)
            ax1.plot(p.x1, p.y1, "+", markersize=7, color=color)
            if p.endpoints is not None:
                ax2.plot(p.endpoints[:, 0], p.endpoints[:, 1], "-", color=color, linewidth=1.5)
            if p.match is not None:
                ax2.plot(*p.match, "o", markersize=7, markerfacecolor="none",
                         markeredgecolor=color, markeredgewidth=2)
                ax2.plot(*p.match, "+", markersize=7, color=color)
        n = len(self.picks)
        ax1.set_title(f"Image 1: {n} selected point{'s' if n != 1 else ''}")
        ax2.set_title("Image 2: epipolar lines" + (" and matches" if matcher else ""))
        warned = sum(p.warning is not None for p in self.picks)
        if warned:
            ax2.text(0.01, 0.01, f"{warned} warning(s): see the notebook output",
                     transform=ax2.transAxes, color="darkorange", fontsize=9,
                     backgroundcolor="white")
        if title:
            fig.suptitle(title)
        fig.tight_layout()
        return fig

    def to_png(self, dpi: int = 80, **kwargs) -> bytes:
        """The static figure as PNG bytes."""
        fig = self.figure(**kwargs)
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi)
        return buf.getvalue()


def _show_image(ax, img: np.ndarray) -> None:
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    ax.imshow(img, cmap="gray", vmin=0.0, vmax=1.0, interpolation="nearest")
    ax.set_xlim(-0.5, img.shape[1] - 0.5)
    ax.set_ylim(img.shape[0] - 0.5, -0.5)
    ax.set_xticks([])
    ax.set_yticks([])


# --------------------------------------------------------------------------------------------
# the notebook front end


def in_kernel() -> bool:
    """True inside a Jupyter kernel (JupyterLab, Notebook, Colab, Voila), where widgets work."""
    try:
        from IPython import get_ipython
    except ImportError:
        return False
    shell = get_ipython()
    return shell is not None and getattr(shell, "kernel", None) is not None


def _enable_colab_widgets() -> None:
    """Colab renders third-party widgets (plotly's FigureWidget) only after this call."""
    if "google.colab" in sys.modules:
        from google.colab import output  # type: ignore[import-not-found]

        output.enable_custom_widget_manager()


def _image_data_uri(img: np.ndarray) -> str:
    import matplotlib.image

    buf = io.BytesIO()
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    matplotlib.image.imsave(buf, np.clip(img, 0.0, 1.0), format="png", cmap="gray",
                            vmin=0.0, vmax=1.0)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _make_figure_widget(session: EpipolarSession, max_side: int):
    """A plotly FigureWidget with both images, or None where FigureWidget cannot be built."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    titles = ("image 1: click a point", "image 2: its epipolar line"
              + (" and match" if session.match_fn is not None else ""))
    fig = make_subplots(rows=1, cols=2, subplot_titles=titles, horizontal_spacing=0.03)
    for col, img in ((1, session.image1), (2, session.image2)):
        # the browser gets a subsampled copy of a large image; dx keeps pixel coordinates
        step = max(1, int(np.ceil(max(img.shape[:2]) / max_side)))
        small = img[::step, ::step]
        fig.add_trace(go.Image(source=_image_data_uri(small), x0=0, y0=0, dx=step, dy=step,
                               name=f"image {col}", hoverlabel=dict(bgcolor="white"),
                               hovertemplate="(%{x}, %{y})<extra></extra>"), row=1, col=col)
    fig.add_trace(go.Scatter(x=[], y=[], mode="markers", name="picks", hoverinfo="skip",
                             marker=dict(size=11, symbol="circle-open-dot", line=dict(width=2))),
                  row=1, col=1)
    fig.add_trace(go.Scatter(x=[], y=[], mode="markers", name="matches", hoverinfo="skip",
                             marker=dict(size=11, symbol="circle-open-dot", line=dict(width=2))),
                  row=1, col=2)
    h = session.image1.shape[0] / session.image1.shape[1]
    fig.update_layout(showlegend=False, margin=dict(l=10, r=10, t=40, b=10),
                      height=int(70 + 400 * h), clickmode="event")
    fig.update_xaxes(showticklabels=False)
    fig.update_yaxes(showticklabels=False)
    try:
        return go.FigureWidget(fig)
    except ImportError:  # plotly >= 6 without anywidget
        return None


class EpipolarApp:
    """The notebook front end of an :class:`EpipolarSession`.

    Made of a plotly ``FigureWidget`` (when plotly can build one: plotly 6+ needs the
    ``anywidget`` package) whose image 1 reacts to clicks, x1/y1 number boxes with a button
    (plain ipywidgets, so they work wherever widgets do), a status line, and below them a
    static PNG of the current picks that is redrawn after each one and is what a saved
    notebook and its PDF keep.

    Parameters
    ----------
    session : EpipolarSession
    use_plotly : bool, optional
        Force (True) or refuse (False) the clickable plotly view; by default it is used when
        available.
    max_side : int
        Images larger than this are subsampled for the browser only (picks stay in pixels
        of the full image).
    """

    def __init__(self, session: EpipolarSession, *, use_plotly: bool | None = None,
                 max_side: int = 1024):
        import ipywidgets as widgets

        self.session = session
        self._plotly_refused = use_plotly is False
        self.figure_widget = None if use_plotly is False else _make_figure_widget(session,
                                                                                   max_side)
        if use_plotly and self.figure_widget is None:
            raise ValueError("use_plotly: plotly cannot build a FigureWidget here "
                             "(with plotly 6 or later, `pip install anywidget`)")
        w1, h1 = session.size1
        matcher = session.match_fn is not None
        self.x_box = widgets.BoundedIntText(value=w1 // 2, min=0, max=w1 - 1, description="x1",
                                            layout=widgets.Layout(width="160px"))
        self.y_box = widgets.BoundedIntText(value=h1 // 2, min=0, max=h1 - 1, description="y1",
                                            layout=widgets.Layout(width="160px"))
        self.pick_button = widgets.Button(description="Match" if matcher else "Show line",
                                          button_style="primary")
        self.clear_button = widgets.Button(description="Clear")
        self.status = widgets.HTML()
        self.pick_button.on_click(lambda _: self.pick(self.x_box.value, self.y_box.value))
        self.clear_button.on_click(lambda _: self.clear())
        if self.figure_widget is not None:
            self.figure_widget.data[0].on_click(self._on_click)
        controls = widgets.HBox([self.x_box, self.y_box, self.pick_button, self.clear_button])
        children = [self.figure_widget] if self.figure_widget is not None else []
        self.widget = widgets.VBox(children + [controls, self.status])
        self._snapshot = None
        self._redraw(None)

    # -- events -------------------------------------------------------------------------------
    def _on_click(self, trace, points, selector) -> None:
        """plotly click callback: ``points.xs``/``points.ys`` hold the clicked pixel."""
        if not points.xs:
            return
        self.pick(points.xs[0], points.ys[0])

    def pick(self, x1, y1) -> EpipolarPick | None:
        """Pick (x1, y1) and update every view; errors go to the status line, not a traceback
        lost in the browser console."""
        try:
            record = self.session.pick(x1, y1)
        except Exception as exc:  # a student's matcher may raise anything
            self._show_status(None, error=f"{type(exc).__name__}: {exc}")
            return None
        self.x_box.value, self.y_box.value = record.x1, record.y1
        self._redraw(record)
        return record

    def clear(self) -> None:
        self.session.clear()
        self._redraw(None)

    # -- views --------------------------------------------------------------------------------
    def _redraw(self, record: EpipolarPick | None) -> None:
        self._show_status(record)
        if self.figure_widget is not None:
            self._update_figure_widget()
        if self._snapshot is not None:
            from IPython.display import Image

            self._snapshot.update(Image(data=self.session.to_png()))

    def _update_figure_widget(self) -> None:
        picks = self.session.picks
        colors = pair_colors(len(picks))
        shapes = [dict(type="line", xref="x2", yref="y2", x0=p.endpoints[0, 0],
                       y0=p.endpoints[0, 1], x1=p.endpoints[1, 0], y1=p.endpoints[1, 1],
                       line=dict(color=c, width=2))
                  for p, c in zip(picks, colors) if p.endpoints is not None]
        with_match = [(p, c) for p, c in zip(picks, colors) if p.match is not None]
        fw = self.figure_widget
        with fw.batch_update():
            fw.data[2].x = [p.x1 for p in picks]
            fw.data[2].y = [p.y1 for p in picks]
            fw.data[2].marker.color = colors
            fw.data[3].x = [p.match[0] for p, _ in with_match]
            fw.data[3].y = [p.match[1] for p, _ in with_match]
            fw.data[3].marker.color = [c for _, c in with_match]
            fw.layout.shapes = shapes

    def _show_status(self, record: EpipolarPick | None, error: str | None = None) -> None:
        n = len(self.session.picks)
        if self.figure_widget is not None:
            how = "Click in image 1 (or type x1 and y1)"
        elif self._plotly_refused:
            how = "Type x1 and y1"
        else:
            how = "Type x1 and y1 (`pip install anywidget` and restart the kernel to click)"
        head = f"{n} pick{'s' if n != 1 else ''}. {how} to add one; 5 or more for the write-up."
        if error is not None:
            body = f'<span class="hw4-error" style="color:#c00">Error: {html.escape(error)}</span>'
        elif record is not None:
            # data-* attributes let a test (or a curious student) read the state back exactly
            attrs = {"x1": record.x1, "y1": record.y1,
                     "line": ",".join(f"{v:.10g}" for v in record.line),
                     "ends": "" if record.endpoints is None
                     else ",".join(f"{v:.6f}" for v in record.endpoints.ravel())}
            if record.match is not None:
                attrs["match"] = f"{record.match[0]:.6f},{record.match[1]:.6f}"
            data = " ".join(f'data-{k}="{v}"' for k, v in attrs.items())
            style = ' style="color:#b60"' if record.warning else ""
            body = f'<span class="hw4-pick"{data and " " + data}{style}>' \
                   f"{html.escape(record.describe())}</span>"
        else:
            body = ""
        self.status.value = f'<div class="hw4-status">{html.escape(head)}<br>{body}</div>'

    def display(self) -> None:
        """Show the widgets, then the static PNG that follows every pick."""
        from IPython.display import Image, display

        if self.figure_widget is not None:
            _enable_colab_widgets()
        # built by hand rather than display(widget): the same on ipywidgets 7 (Colab) and 8, and
        # the text shown where widgets cannot render (an exported PDF) stays short and useful
        bundle = {
            "application/vnd.jupyter.widget-view+json": {
                "version_major": 2, "version_minor": 0, "model_id": self.widget.model_id},
            "text/plain": "Interactive epipolar viewer (its current state is the image below)",
        }
        display(bundle, raw=True)
        self._snapshot = display(Image(data=self.session.to_png()), display_id=True)


# --------------------------------------------------------------------------------------------
# the two helpers of the handout


def _run(session: EpipolarSession, points, interactive: bool | None) -> EpipolarSession:
    if points is not None:
        pts = as_points(points, "points", dims=2, allow_extra_columns=False)
        for x, y in pts:
            record = session.pick(x, y)
            if record.warning:
                warnings.warn(f"point ({record.x1}, {record.y1}): {record.warning}", stacklevel=3)
    if interactive is None:
        interactive = points is None
    kernel = in_kernel()
    if interactive and kernel:
        app = EpipolarApp(session)
        session.app = app
        app.display()
        return session
    if interactive:
        warnings.warn("interactive picking needs a Jupyter kernel (JupyterLab, Notebook, Colab); "
                      "pass points=[[x1, y1], ...] for the static figure", stacklevel=3)
    if kernel:
        from IPython.display import Image, display

        display(Image(data=session.to_png()))
    return session


def displayEpipolarF(I1, I2, F, points=None, *, interactive: bool | None = None, matches=None):
    """Show the epipolar lines in image 2 of points of image 1.

    Parameters
    ----------
    I1, I2 : array_like, shape (H, W) or (H, W, 3)
        uint8, or float in [0, 1].
    F : array_like, shape (3, 3)
        Fundamental matrix, ``x2^T F x1 = 0``.
    points : array_like, shape (K, 2), optional
        Pixels (x1, y1) of image 1.  Given: the static figure of their lines is displayed.
        Omitted: the interactive picker (click in image 1, or type x1/y1).
    interactive : bool, optional
        Show the picker even though ``points`` were given (they are its first picks).
    matches : array_like, shape (K, 2), optional
        The known matches (x2, y2) in image 2 of ``points``, row by row: drawn on image 2 in the
        colour of their line, so that a reader sees each line pass through its match (the
        figure of Q2).  Needs ``points`` of the same length.

    Returns
    -------
    EpipolarSession
        Its ``picks`` hold every line; ``session.figure()`` redraws the static figure.
    """
    if matches is None:
        return _run(EpipolarSession(I1, I2, F), points, interactive)
    if points is None:
        raise ValueError("matches: expected them with points (the matches of those points), got no points")
    known = as_points(matches, "matches", dims=2, allow_extra_columns=False)
    pts = as_points(points, "points", dims=2, allow_extra_columns=False)
    if len(known) != len(pts):
        raise ValueError(f"matches: expected one match per point ({len(pts)}), got {len(known)}")
    given = iter(known)
    session = EpipolarSession(I1, I2, F, lambda *_: next(given), far_threshold=5.0)
    session = _run(session, pts, interactive)
    session.match_fn = None  # later picks (the interactive picker) have no known match
    return session


def epipolarMatchGUI(I1, I2, F, match_fn, points=None, *, interactive: bool | None = None,
                     far_threshold: float = 2.0):
    """Show epipolar lines and the matches found by ``match_fn`` (``epipolarCorrespondence``).

    Parameters
    ----------
    I1, I2 : array_like, shape (H, W) or (H, W, 3)
        uint8, or float in [0, 1]; ``match_fn`` receives them as given.
    F : array_like, shape (3, 3)
        Fundamental matrix, ``x2^T F x1 = 0``.
    match_fn : callable
        ``match_fn(I1, I2, F, x1, y1) -> (x2, y2)``, called with integer pixel coordinates.
    points : array_like, shape (K, 2), optional
        Pixels (x1, y1) of image 1 (at least 5 for the write-up).  Given: the static figure is
        displayed.  Omitted: the interactive picker.
    interactive : bool, optional
        Show the picker even though ``points`` were given.
    far_threshold : float
        Warn when a match lies farther than this from its epipolar line, in pixels.

    Returns
    -------
    EpipolarSession
    """
    if match_fn is None or not callable(match_fn):
        raise ValueError(f"match_fn: expected a function (im1, im2, F, x1, y1) -> (x2, y2), "
                         f"got {type(match_fn).__name__}")
    session = EpipolarSession(I1, I2, F, match_fn, far_threshold=far_threshold)
    return _run(session, points, interactive)
