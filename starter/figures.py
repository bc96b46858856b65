"""3D point figures that rotate on screen and still print.

A notebook cell that ends with ``plot_points_3d(P)`` displays one output whose MIME bundle holds
three renderings of the same data:

``application/vnd.plotly.v1+json``
    The plotly figure; JupyterLab, VS Code and nteract draw it as a rotatable 3D plot.
``text/html``
    What Google Colab (and the classic notebook) draw.  It shows a PNG at once and, once plotly.js
    has loaded from the CDN, swaps in the rotatable plot.  A print stylesheet keeps the PNG in
    print, so an HTML export printed to PDF by Chromium (``jupyter nbconvert --to webpdf``, or
    ``--to html`` then ``chromium --print-to-pdf``, which both pick ``text/html`` first) always
    carries the still image, with or without network.
``image/png``
    A matplotlib rendering of the same points, what ``nbconvert --to pdf`` (LaTeX) uses and what
    JupyterLab falls back to for an untrusted notebook.

Why plotly.js from the CDN rather than inline: inlining adds about 4.8 MB of JavaScript to every
figure of the saved notebook (four 3D figures would make a 20 MB submission); from the CDN the
``text/html`` part costs only the figure's JSON and its PNG.  The CDN is reached only where
``text/html`` is the rendering in use (Colab, which is online by definition); offline JupyterLab
uses the plotly MIME renderer shipped in the ``plotly`` wheel, and every PDF path uses the PNG.
No kaleido or Chrome is needed anywhere: the PNG comes from matplotlib.

Coordinates are drawn as given, with one scale on all three axes.  Rows of NaN are points that
were not reconstructed; they are skipped, and so is every edge that touches one.
"""

from __future__ import annotations

import base64
import html
import io
import json
import uuid
from collections.abc import Sequence

import numpy as np

from core.validate import as_points

__all__ = ["Figure3D", "plot_points_3d", "points_with_gaps", "DEFAULT_COLORS", "plotly_cdn_url",
           "crowded_labels"]

#: Colours given to successive point sets (matplotlib's tab10, as hex so plotly reads them too).
DEFAULT_COLORS: tuple[str, ...] = (
    "#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd",
    "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf",
)

_LAYOUTS = ("overlay", "side_by_side")
_UPS = ("-y", "y", "z")


def _viewer_direction(up: str, elev: float, azim: float) -> np.ndarray:
    """Unit vector from the centre of the data towards the viewer.

    ``elev`` is the height above the horizontal plane (the plane normal to ``up``) and
    ``azim`` the turn about ``up``.  For the y modes, (0, 0) is straight behind camera 1
    (looking along +Z); for "z" it follows matplotlib (azim 0 looks from +X).
    """
    e, a = np.radians(elev), np.radians(azim)
    if up == "-y":
        return np.array([np.cos(e) * np.sin(a), -np.sin(e), -np.cos(e) * np.cos(a)])
    if up == "y":
        return np.array([np.cos(e) * np.sin(a), np.sin(e), -np.cos(e) * np.cos(a)])
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


def _matplotlib_view(up: str, elev: float, azim: float) -> dict:
    """``Axes3D.view_init`` arguments that put the viewer where :func:`_viewer_direction` says."""
    if up == "z":
        return dict(elev=elev, azim=azim)
    # with vertical_axis="y" matplotlib's viewer sits at (cos e sin a, sin e, cos e cos a);
    # a roll of 180 degrees turns the picture over so that -Y points up the screen
    if up == "y":
        return dict(elev=elev, azim=180.0 - azim, vertical_axis="y")
    return dict(elev=-elev, azim=180.0 - azim, roll=180.0, vertical_axis="y")


def plotly_cdn_url() -> str:
    """URL of the plotly.js build that matches the installed plotly package."""
    from plotly.offline import get_plotlyjs_version

    return f"https://cdn.plot.ly/plotly-{get_plotlyjs_version()}.min.js"


class Figure3D:
    """One 3D figure held twice: as a plotly figure (on screen) and a matplotlib figure (on paper).

    Leave it as the last expression of a notebook cell, or call :meth:`show`, to display both at
    once (see the module docstring for which front end uses which).

    Attributes
    ----------
    plotly : plotly.graph_objects.Figure
        The interactive figure.
    matplotlib : matplotlib.figure.Figure
        The static figure.  It is not registered with pyplot, so it never shows up twice.
    title : str
        The figure title (may be empty).
    """

    def __init__(self, plotly_figure, matplotlib_figure, title: str = "", *, dpi: int = 100):
        self.plotly = plotly_figure
        self.matplotlib = matplotlib_figure
        self.title = title
        self.dpi = dpi
        self._png: bytes | None = None

    def __repr__(self) -> str:
        n = len(self.plotly.data)
        return f"<Figure3D {self.title!r}: {n} plotly trace{'s' if n != 1 else ''}>"

    def to_png(self) -> bytes:
        """The matplotlib rendering as PNG bytes (computed once, then cached)."""
        if self._png is None:
            buf = io.BytesIO()
            self.matplotlib.savefig(buf, format="png", dpi=self.dpi)
            self._png = buf.getvalue()
        return self._png

    def savefig(self, path, **kwargs) -> None:
        """Save the static rendering (any format matplotlib writes: .png, .pdf, .svg)."""
        kwargs.setdefault("dpi", self.dpi)
        self.matplotlib.savefig(path, **kwargs)

    def plotly_json(self) -> dict:
        """The plotly figure as a JSON-compatible dict (data, layout, config)."""
        import plotly.io as pio

        fig = json.loads(pio.to_json(self.plotly, validate=False, remove_uids=False))
        fig.setdefault("config", {})
        fig["config"].setdefault("responsive", True)
        return fig

    def to_html(self) -> str:
        """An HTML fragment: the PNG now, the rotatable plot once plotly.js is available.

        The PNG stays the printed rendering (``@media print``), so a PDF made from exported
        HTML never depends on JavaScript or on the network.
        """
        uid = "hw4fig-" + uuid.uuid4().hex[:12]
        png = base64.b64encode(self.to_png()).decode("ascii")
        # "</" inside a <script> would end it early if a title contained "</script>".
        fig_json = json.dumps(self.plotly_json()).replace("</", "<\\/")
        cdn = plotly_cdn_url()
        height = int(self.plotly.layout.height or 520)
        alt = html.escape(self.title or "3D figure", quote=True)
        return f"""<div id="{uid}" class="hw4-figure3d">
<style>
#{uid} .hw4-live {{ display: none; width: 100%; height: {height}px; }}
@media print {{
  #{uid} .hw4-live {{ display: none !important; }}
  #{uid} .hw4-still {{ display: block !important; }}
}}
</style>
<img class="hw4-still" alt="{alt}" style="max-width: 100%;" src="data:image/png;base64,{png}"/>
<div class="hw4-live"></div>
<script type="text/javascript">
(function () {{
  var root = document.getElementById("{uid}");
  if (!root) {{ return; }}
  var fig = {fig_json};
  function draw(Plotly) {{
    if (!Plotly || !Plotly.newPlot) {{ return; }}
    var live = root.querySelector(".hw4-live");
    live.style.display = "block";
    Plotly.newPlot(live, fig.data, fig.layout, fig.config).then(function () {{
      root.querySelector(".hw4-still").style.display = "none";
    }}, function () {{ live.style.display = "none"; }});
  }}
  if (window.Plotly) {{ draw(window.Plotly); return; }}
  var url = "{cdn}";
  if (typeof window.require === "function" && window.require.config) {{
    // Under require.js (classic notebook) plotly.js registers as a module, not as window.Plotly.
    window.require.config({{ paths: {{ hw4plotly: url.replace(/\\.js$/, "") }} }});
    window.require(["hw4plotly"], draw, function () {{}});
    return;
  }}
  var s = document.createElement("script");
  s.src = url;
  s.charset = "utf-8";
  s.onload = function () {{ draw(window.Plotly); }};
  document.head.appendChild(s);
}})();
</script>
</div>"""

    def mimebundle(self) -> dict:
        """The display data: plotly JSON, HTML, PNG and a text fallback."""
        return {
            "application/vnd.plotly.v1+json": self.plotly_json(),
            "text/html": self.to_html(),
            "image/png": base64.b64encode(self.to_png()).decode("ascii"),
            "text/plain": repr(self),
        }

    def _repr_mimebundle_(self, include=None, exclude=None):
        data = self.mimebundle()
        if include:
            data = {k: v for k, v in data.items() if k in include}
        if exclude:
            data = {k: v for k, v in data.items() if k not in exclude}
        return data

    def show(self) -> None:
        """Display the figure in the running notebook (prints its repr elsewhere)."""
        from IPython.display import display

        display(self)


# --------------------------------------------------------------------------------------------
# input handling


def points_with_gaps(value, name: str) -> np.ndarray:
    """Return ``value`` as float64 (N, 3), where a row holding any NaN marks a missing point.

    Everything else goes through :func:`core.validate.as_points`, so a wrong shape, a
    non-numeric array or an infinite value raises the usual ValueError naming ``name``.
    The returned array has every coordinate of a missing row set to NaN.
    """
    arr = np.asarray(value) if not isinstance(value, np.ndarray) else value
    missing = None
    if arr.dtype.kind == "f" and arr.ndim == 2:
        missing = np.isnan(arr).any(axis=1)
        arr = np.where(np.isnan(arr), 0.0, arr)
    out = as_points(arr, name, dims=3, min_count=0)
    if missing is not None:
        out[missing] = np.nan
    return out


def _as_point_sets(points) -> list[np.ndarray]:
    if points is None:
        raise ValueError("points: expected an (N, 3) array or a list of them, got None")
    if isinstance(points, np.ndarray) and points.ndim == 3:
        return [points_with_gaps(p, f"points[{i}]") for i, p in enumerate(points)]
    if isinstance(points, (list, tuple)) and len(points) > 0 and np.ndim(points[0]) == 2:
        return [points_with_gaps(p, f"points[{i}]") for i, p in enumerate(points)]
    return [points_with_gaps(points, "points")]


def _as_labels(labels, count: int) -> list[str]:
    if labels is None:
        return [""] * count if count == 1 else [f"set {i + 1}" for i in range(count)]
    if isinstance(labels, str):
        labels = [labels]
    labels = [str(x) for x in labels]
    if len(labels) != count:
        raise ValueError(f"labels: expected {count} label(s), one per point set, got {len(labels)}")
    return labels


def _as_edges(edges, sets: list[np.ndarray]) -> np.ndarray:
    if edges is None:
        return np.zeros((0, 2), dtype=int)
    arr = np.asarray(edges)
    if arr.size == 0:
        return np.zeros((0, 2), dtype=int)
    if arr.ndim != 2 or arr.shape[1] != 2 or arr.dtype.kind not in "iu":
        raise ValueError(f"edges: expected integer index pairs of shape (E, 2), "
                         f"got an array of shape {arr.shape} and dtype {arr.dtype}")
    for i, p in enumerate(sets):
        if arr.min() < 0 or arr.max() >= len(p):
            raise ValueError(f"edges: indices must lie in [0, {len(p) - 1}] for point set {i} "
                             f"of {len(p)} points, got indices from {arr.min()} to {arr.max()}")
    return arr.astype(int)


def _as_colors(colors, count: int) -> list[str]:
    if colors is None:
        return [DEFAULT_COLORS[i % len(DEFAULT_COLORS)] for i in range(count)]
    if isinstance(colors, str):
        colors = [colors]
    colors = list(colors)
    if len(colors) != count:
        raise ValueError(f"colors: expected {count} colour(s), one per point set, got {len(colors)}")
    from matplotlib.colors import to_hex

    try:
        return [to_hex(c) for c in colors]
    except ValueError as exc:
        raise ValueError(f"colors: expected matplotlib colour names or hex strings ({exc})") from None


def _edge_segments(P: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(K, 2, 3) segments for the edges whose two ends both exist."""
    if len(edges) == 0:
        return np.zeros((0, 2, 3))
    seg = np.stack([P[edges[:, 0]], P[edges[:, 1]]], axis=1)
    return seg[np.isfinite(seg).all(axis=(1, 2))]


def _bounds(arrays: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned box around the finite points, never flat (so the aspect stays defined)."""
    pts = np.concatenate([a[np.isfinite(a).all(axis=1)] for a in arrays] + [np.zeros((0, 3))])
    if len(pts) == 0:
        return -np.ones(3), np.ones(3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = hi - lo
    pad = np.maximum(0.02 * span.max(), 1e-9) if span.max() > 0 else 1.0
    # a flat axis gets a sliver of thickness so the box aspect stays finite
    return lo - pad, hi + pad


# --------------------------------------------------------------------------------------------
# the two renderings


def _plotly_figure(sets, labels, colors, edges, hover_text, title, layout, marker_size,
                   line_width, axis_titles, up, view, height):
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    n = len(sets)
    side = layout == "side_by_side" and n > 1
    if side:
        fig = make_subplots(rows=1, cols=n, specs=[[{"type": "scene"}] * n],
                            subplot_titles=labels, horizontal_spacing=0.02)
    else:
        fig = go.Figure()
    for i, (P, label, color) in enumerate(zip(sets, labels, colors)):
        ok = np.isfinite(P).all(axis=1)
        scene = f"scene{i + 1}" if side and i > 0 else "scene"
        name = label or "points"
        text = None if hover_text is None else [hover_text[j] for j in np.flatnonzero(ok)]
        fig.add_trace(go.Scatter3d(
            x=P[ok, 0], y=P[ok, 1], z=P[ok, 2], mode="markers", name=name, legendgroup=name,
            marker=dict(size=marker_size, color=color), text=text, scene=scene,
            showlegend=bool(label) and not side))
        seg = _edge_segments(P, edges)
        if len(seg):
            # one trace per set: segments separated by None break the polyline
            xyz = np.full((len(seg) * 3, 3), np.nan)
            xyz[0::3], xyz[1::3] = seg[:, 0], seg[:, 1]
            cols = [[None if np.isnan(v) else float(v) for v in xyz[:, k]] for k in range(3)]
            fig.add_trace(go.Scatter3d(
                x=cols[0], y=cols[1], z=cols[2], mode="lines", name=f"{name} edges",
                legendgroup=name, showlegend=False, hoverinfo="skip",
                line=dict(color=color, width=line_width), scene=scene))
    up_vector = {"-y": (0, -1, 0), "y": (0, 1, 0), "z": (0, 0, 1)}[up]
    eye = 2.0 * _viewer_direction(up, *view)
    camera = dict(up=dict(zip("xyz", up_vector)), eye=dict(zip("xyz", eye.tolist())))
    axes = dict(xaxis=dict(title=axis_titles[0], nticks=_MAX_TICK_BINS + 1),
                yaxis=dict(title=axis_titles[1], nticks=_MAX_TICK_BINS + 1),
                zaxis=dict(title=axis_titles[2], nticks=_MAX_TICK_BINS + 1),
                aspectmode="data", camera=camera)
    for i in range(n if side else 1):
        fig.layout[f"scene{i + 1}" if i > 0 else "scene"].update(axes)
    fig.update_layout(title=title or None, height=height, margin=dict(l=0, r=0, t=60, b=0))
    return fig


def _matplotlib_figure(sets, labels, colors, edges, title, layout, marker_size, line_width,
                       axis_titles, up, view, size_inches):
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    n = len(sets)
    side = layout == "side_by_side" and n > 1
    width, height = size_inches
    fig = Figure(figsize=(width * (n if side else 1) * (0.85 if side else 1), height))
    groups = [[i] for i in range(n)] if side else [list(range(n))]
    for k, members in enumerate(groups):
        ax = fig.add_subplot(1, len(groups), k + 1, projection="3d")
        for i in members:
            P = sets[i]
            ok = np.isfinite(P).all(axis=1)
            ax.scatter(P[ok, 0], P[ok, 1], P[ok, 2], s=marker_size ** 2, color=colors[i],
                       depthshade=False, label=labels[i] or None)
            seg = _edge_segments(P, edges)
            if len(seg):
                ax.add_collection3d(Line3DCollection(seg, colors=colors[i],
                                                     linewidths=line_width / 2))
        lo, hi = _bounds([sets[i] for i in members])
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_zlim(lo[2], hi[2])
        # The view first: set_box_aspect stores the aspect rolled for the current vertical axis,
        # so setting it before view_init(vertical_axis="y") would give X the span of Y and so on.
        ax.view_init(**_matplotlib_view(up, *view))
        # one unit is one unit on every axis: the box takes the data's proportions
        ax.set_box_aspect(hi - lo)
        for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
            axis.set_major_locator(MaxNLocator(_MAX_TICK_BINS))
        ax.set_xlabel(axis_titles[0])
        ax.set_ylabel(axis_titles[1])
        ax.set_zlabel(axis_titles[2])
        if side:
            ax.set_title(labels[i])
    legend = not side and n > 1 and any(labels)
    if legend:
        # below the view, in rows of at most ten, so that it never covers a point
        handles, names = fig.axes[0].get_legend_handles_labels()
        fig.legend(handles, names, loc="lower center", ncols=min(len(names), 10 if n > 5 else 5),
                   fontsize="small", frameon=False, handletextpad=0.2, columnspacing=1.0)
    if title:
        fig.suptitle(title)
    rows = -(-n // (10 if n > 5 else 5)) if legend else 0
    fig.tight_layout(rect=(0.0, 0.05 * rows, 1.0, 1.0))
    _thin_crowded_ticks(fig)
    return fig


#: At most this many intervals between ticks (so at most five tick labels per axis).
_MAX_TICK_BINS = 4


def _label_boxes(fig, renderer) -> list[tuple[object, bool, object]]:
    """(axis, is_title, bounding box) of every drawn tick label and axis title of the 3D axes."""
    boxes = []
    for ax in fig.axes:
        if ax.name != "3d":
            continue
        for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
            lo, hi = sorted(axis.get_view_interval())
            locs = axis.get_majorticklocs()
            for loc, tick in zip(locs, axis.get_major_ticks(len(locs))):
                if lo <= loc <= hi and tick.label1.get_visible() and tick.label1.get_text():
                    boxes.append((axis, False, tick.label1.get_window_extent(renderer)))
            if axis.label.get_text():
                boxes.append((axis, True, axis.label.get_window_extent(renderer)))
    return boxes


def crowded_labels(fig, pad: float = 2.0) -> list[tuple[object, bool, object, bool]]:
    """Pairs of 3D-axes labels (tick labels and axis titles) closer than ``pad`` pixels.

    Each pair is (axis_a, a_is_title, axis_b, b_is_title).  The figure is drawn first (without
    rendering pixels), so the positions are those of the saved PNG at the figure's dpi.
    """
    fig.draw_without_rendering()
    boxes = _label_boxes(fig, fig._get_renderer())
    pairs = []
    for i, (axis_a, title_a, a) in enumerate(boxes):
        for axis_b, title_b, b in boxes[i + 1:]:
            if a.padded(pad).overlaps(b):
                pairs.append((axis_a, title_a, axis_b, title_b))
    return pairs


def _thin_crowded_ticks(fig, rounds: int = 16, step: float = 4.0) -> None:
    """Take ticks away from axes whose labels touch, and move titles off the labels they touch.

    A foreshortened axis (one seen nearly end-on) gets its tick labels close together.  Each
    round draws the figure and then: an axis whose tick labels touch other tick labels gets one
    tick interval fewer (down to one); a title touching a label is moved ``step`` points further
    from its axis (of two touching titles, the later axis' one; once it cannot, the other one
    moves closer to its axis), unless that would take it out of the figure.  It stops when nothing touches or nothing more can be done.
    """
    from matplotlib.ticker import MaxNLocator

    bins: dict[int, int] = {}
    stuck: set[int] = set()          # titles that would leave the figure if moved further
    for _ in range(rounds):
        pairs = crowded_labels(fig)
        if not pairs:
            return
        to_push, to_thin, pulled = {}, {}, False
        for axis_a, title_a, axis_b, title_b in pairs:
            if title_a and title_b:
                # the later axis' title moves out; once it cannot, the other one moves in
                if id(axis_b) not in stuck:
                    to_push[id(axis_b)] = axis_b
                elif axis_a.labelpad > -4 * step:
                    axis_a.labelpad -= step
                    pulled = True
            elif title_a or title_b:
                axis = axis_a if title_a else axis_b
                to_push[id(axis)] = axis
            else:
                to_thin[id(axis_a)] = axis_a
                to_thin[id(axis_b)] = axis_b
        changed = pulled
        for key, axis in to_thin.items():
            n = bins.get(key, _MAX_TICK_BINS)
            if n > 1:
                bins[key] = n - 1
                axis.set_major_locator(MaxNLocator(n - 1))
                changed = True
        for key, axis in to_push.items():
            if key not in stuck:
                axis.labelpad += step
                changed = True
        if to_push:
            fig.draw_without_rendering()
            inside = fig.bbox
            renderer = fig._get_renderer()
            for key, axis in to_push.items():
                box = axis.label.get_window_extent(renderer)
                if key not in stuck and not (box.x0 >= inside.x0 and box.x1 <= inside.x1
                                             and box.y0 >= inside.y0 and box.y1 <= inside.y1):
                    axis.labelpad -= step
                    stuck.add(key)
        if not changed:
            return


def plot_points_3d(points, labels=None, title: str = "", *, edges=None, layout: str = "overlay",
                   colors=None, hover_text: Sequence[str] | None = None,
                   marker_size: float = 3.0, line_width: float = 4.0,
                   axis_titles: Sequence[str] = ("X (right)", "Y (down)", "Z (depth)"),
                   up: str = "-y", view: tuple[float, float] = (15.0, -30.0),
                   size_inches: tuple[float, float] = (6.4, 5.0), dpi: int = 100,
                   height: int = 520) -> Figure3D:
    """Plot one or more 3D point sets, rotatable on screen, with a PNG for the PDF.

    Parameters
    ----------
    points : array_like, shape (N, 3), or a sequence of them, or an array of shape (S, N, 3)
        World points, one per row.  A row holding a NaN is a point that does not exist (a car
        keypoint that was not reconstructed): it is not drawn, nor is any edge that touches it.
    labels : str or sequence of str, optional
        One name per point set (legend entries, or subplot titles side by side).
    title : str
        Figure title.
    edges : array_like of int, shape (E, 2), optional
        Index pairs (i, j) joined by a line in every point set (a skeleton such as
        ``core.skeleton.CAR_SKELETON``).
    layout : {"overlay", "side_by_side"}
        All sets in one 3D view, or one view per set (bundle adjustment before/after).
    colors : sequence of colours, optional
        One per set; matplotlib names or hex strings.  Defaults to :data:`DEFAULT_COLORS`.
    hover_text : sequence of str, optional
        One label per point row, shown on hover (for example the keypoint names).
    marker_size, line_width : float
        Marker diameter and edge width, in plotly's pixel units (matplotlib scales them).
    axis_titles : 3 str
        Axis names with their conventions; the default names camera coordinates (camera 1's X
        right, Y down, Z forward along the optical axis), the frame of the temple.
    up : {"-y", "y", "z"}
        The world direction drawn upwards.  The default suits this homework, whose points are in
        camera coordinates (X right, Y down, Z forward) or, for the car, a world frame whose -Y
        is up: the temple and the car stand the right way up.
    view : (elev, azim)
        Starting viewpoint of both renderings, in degrees: height above the horizontal plane and
        turn about ``up``.  For ``up="-y"`` or ``"y"``, (0, 0) looks along +Z from behind
        camera 1 and a positive ``azim`` moves the viewer towards +X.  The default looks from
        slightly above and to the left of camera 1, so the front of the object and its depth
        both show.
    size_inches, dpi :
        Size of the static figure per view and the PNG resolution.
    height : int
        Height of the on-screen plotly figure in pixels.

    Returns
    -------
    Figure3D
        Shown when it is the last expression of a cell, or by ``.show()``.

    Raises
    ------
    ValueError
        When an argument has the wrong shape or type; the message names it.

    Examples
    --------
    >>> import numpy as np
    >>> P = np.random.default_rng(0).normal(size=(50, 3))
    >>> fig = plot_points_3d(P, title="cloud")
    >>> sorted(fig.mimebundle())[:2]
    ['application/vnd.plotly.v1+json', 'image/png']
    """
    sets = _as_point_sets(points)
    if not any(np.isfinite(p).all(axis=1).any() for p in sets):
        raise ValueError("points: expected at least one point without NaN, got none")
    if layout not in _LAYOUTS:
        raise ValueError(f"layout: expected one of {_LAYOUTS}, got {layout!r}")
    labels = _as_labels(labels, len(sets))
    colors = _as_colors(colors, len(sets))
    edges = _as_edges(edges, sets)
    if hover_text is not None:
        hover_text = [str(t) for t in hover_text]
        if any(len(p) != len(hover_text) for p in sets):
            raise ValueError(f"hover_text: expected one string per point row "
                             f"({[len(p) for p in sets]}), got {len(hover_text)}")
    if len(axis_titles) != 3:
        raise ValueError(f"axis_titles: expected 3 strings, got {len(axis_titles)}")
    if up not in _UPS:
        raise ValueError(f"up: expected one of {_UPS}, got {up!r}")
    if len(view) != 2 or not np.all(np.isfinite(np.asarray(view, dtype=float))):
        raise ValueError(f"view: expected two finite angles (elev, azim), got {view!r}")
    view = (float(view[0]), float(view[1]))
    title = "" if title is None else str(title)
    pfig = _plotly_figure(sets, labels, colors, edges, hover_text, title, layout, marker_size,
                          line_width, axis_titles, up, view, height)
    mfig = _matplotlib_figure(sets, labels, colors, edges, title, layout, marker_size,
                              line_width, axis_titles, up, view, size_inches)
    return Figure3D(pfig, mfig, title, dpi=dpi)
