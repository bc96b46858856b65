"""starter.figures and starter.keypoints: one output that rotates on screen and prints on paper."""

from __future__ import annotations

import base64
import io
import itertools
import sys

import matplotlib.image
import numpy as np
import pytest
from matplotlib.figure import Figure

from starter.figures import Figure3D, plot_points_3d, plotly_cdn_url
from starter.keypoints import plot_3d_keypoint, plot_3d_keypoint_frames, visualize_keypoints
from core.paths import KIT_ROOT
from core.skeleton import CAR_SKELETON

pytestmark = pytest.mark.slow  # the full tier's: see docs/testing.md

PLOTLY_MIME = "application/vnd.plotly.v1+json"


# -- helpers ----------------------------------------------------------------------------------

def plotly_array(value) -> np.ndarray:
    """A plotly JSON array (a list with None gaps, or a base64 typed array) as float64."""
    if isinstance(value, dict) and "bdata" in value:
        arr = np.frombuffer(base64.b64decode(value["bdata"]), dtype=np.dtype(value["dtype"]))
        return arr.astype(float)
    return np.array([np.nan if v is None else v for v in value], dtype=float)


def traces(fig: Figure3D, mode: str) -> list[dict]:
    return [t for t in fig.plotly_json()["data"] if t.get("mode") == mode]


def xyz(trace: dict) -> np.ndarray:
    return np.column_stack([plotly_array(trace[k]) for k in "xyz"])


def segments_of(trace: dict) -> np.ndarray:
    """(K, 2, 3) segments of a lines trace whose segments are separated by gaps."""
    pts = xyz(trace)
    assert len(pts) % 3 == 0 and np.isnan(pts[2::3]).all(), "segments must be separated by gaps"
    return np.stack([pts[0::3], pts[1::3]], axis=1)


def same_segments(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal as unordered sets of undirected segments."""
    key = lambda s: tuple(sorted(map(tuple, np.round(s, 9))))
    return sorted(map(key, a)) == sorted(map(key, b))


def axes3d(fig: Figure3D):
    return [ax for ax in fig.matplotlib.axes if ax.name == "3d"]


@pytest.fixture
def car(rng) -> np.ndarray:
    """A car-like (12, 3) keypoint set: three layers of four, -Y up."""
    base = np.array([[x, y, z] for y in (0.4, 0.2, 0.0) for z in (0.0, 1.0)
                     for x in (0.0, 2.0)], dtype=float)
    # rows: wheels FL FR RL RR, lights, roof, as in CAR_KEYPOINTS (x along, z across)
    base = base[[0, 2, 1, 3, 4, 6, 5, 7, 8, 10, 9, 11]]
    return base + rng.normal(scale=0.01, size=base.shape)


# -- the display bundle -----------------------------------------------------------------------

def test_bundle_holds_plotly_json_html_and_png_through_ipython(rng):
    from IPython.core.formatters import DisplayFormatter

    P = rng.normal(size=(40, 3))
    fig = plot_points_3d(P, title="cloud", size_inches=(6.4, 5.0), dpi=50)
    data, _ = DisplayFormatter().format(fig)
    assert {PLOTLY_MIME, "text/html", "image/png", "text/plain"} <= set(data)

    png = base64.b64decode(data["image/png"])
    img = matplotlib.image.imread(io.BytesIO(png), format="png")
    assert img.shape[:2] == (250, 320)
    assert img[..., :3].std() > 0.01, "the PNG should show something, not a blank canvas"

    (markers,) = [t for t in data[PLOTLY_MIME]["data"] if t["mode"] == "markers"]
    assert markers["type"] == "scatter3d"
    np.testing.assert_allclose(xyz(markers), P)
    assert data[PLOTLY_MIME]["layout"]["title"]["text"] == "cloud"


def test_html_shows_the_png_prints_it_and_loads_plotly_from_the_cdn(rng):
    fig = plot_points_3d(rng.normal(size=(10, 3)), title="a </script> title")
    page = fig.to_html()
    png = base64.b64encode(fig.to_png()).decode()
    assert f'src="data:image/png;base64,{png}"' in page
    assert "@media print" in page and ".hw4-still { display: block !important; }" in page
    assert plotly_cdn_url() in page
    # plotly.js itself is not inlined (it would add megabytes to every saved figure)
    assert len(page) < 2 * len(png) + 50_000
    # a title cannot end the script early
    assert page.count("</script>") == 1


@pytest.mark.slow
def test_notebook_cell_output_keeps_every_rendering(tmp_path):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    code = (f"import sys; sys.path.insert(0, {str(KIT_ROOT)!r})\n"
            "import numpy as np\n"
            "from starter.figures import plot_points_3d\n"
            "plot_points_3d(np.random.default_rng(1).normal(size=(20, 3)), title='x')")
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(code)])
    nbclient.NotebookClient(nb, timeout=120, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    (out,) = nb.cells[0].outputs
    assert out["output_type"] == "execute_result"
    assert {PLOTLY_MIME, "text/html", "image/png"} <= set(out["data"])
    matplotlib.image.imread(io.BytesIO(base64.b64decode(out["data"]["image/png"])), format="png")


# -- geometry of the figure -------------------------------------------------------------------

def screen_jacobian(ax) -> np.ndarray:
    """(3, 2): display pixels moved per data unit along X, Y, Z, at the middle of the 3D box.

    Measured on the drawn figure through matplotlib's own projection, so it shows what the PNG
    shows whatever the axes store internally.  At the middle of the box the perspective divide
    scales all three directions alike, so equal data scales give columns of equal length at
    right angles (the 3 rows are a scaled orthographic projection).
    """
    from mpl_toolkits.mplot3d import proj3d

    ax.figure.draw_without_rendering()
    centre = np.array([np.mean(ax.get_xlim()), np.mean(ax.get_ylim()), np.mean(ax.get_zlim())])
    h = 1e-4 * max(np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim()), np.ptp(ax.get_zlim()))
    pts = np.vstack([centre, centre + h * np.eye(3)])
    x, y, _ = proj3d.proj_transform(pts[:, 0], pts[:, 1], pts[:, 2], ax.get_proj())
    xy = ax.transData.transform(np.column_stack([x, y]))
    return (xy[1:] - xy[0]) / h


def to_screen(ax, P: np.ndarray) -> np.ndarray:
    from mpl_toolkits.mplot3d import proj3d

    x, y, _ = proj3d.proj_transform(P[:, 0], P[:, 1], P[:, 2], ax.get_proj())
    return ax.transData.transform(np.column_stack([x, y]))


def assert_equal_scale(ax):
    J = screen_jacobian(ax)
    G = J.T @ J  # 2x2: squared lengths and dot product of the screen axes' preimages
    assert abs(G[0, 1]) < 0.01 * np.sqrt(G[0, 0] * G[1, 1]), f"axes drawn sheared: {G}"
    assert abs(np.sqrt(G[0, 0] / G[1, 1]) - 1) < 0.01, f"unequal data scales on screen: {G}"


def car_video(car, heading_deg: float, T: int = 10, step: float = 0.9) -> np.ndarray:
    """(T, 12, 3): the fixture car turned to ``heading_deg`` in the X-Z ground plane and driven
    ``step`` per frame along it (-Y up, as in the homework's world frames)."""
    a = np.radians(heading_deg)
    R = np.array([[np.cos(a), 0.0, -np.sin(a)], [0.0, 1.0, 0.0], [np.sin(a), 0.0, np.cos(a)]])
    body = (car - car.mean(axis=0)) * [-1.0, 1.0, -1.0]  # the fixture's front is at -X: turn it
    body = body @ R.T
    direction = np.array([np.cos(a), 0.0, np.sin(a)])
    return np.stack([body + [3.0, -0.2, -1.0] + step * t * direction for t in range(T)])


def test_equal_scale_on_all_three_axes(rng):
    P = rng.uniform(size=(100, 3)) * [2.0, 1.0, 4.0] + [5.0, -3.0, 10.0]
    fig = plot_points_3d(P)
    assert fig.plotly_json()["layout"]["scene"]["aspectmode"] == "data"
    (ax,) = axes3d(fig)
    lo = [min(ax.get_xlim()), min(ax.get_ylim()), min(ax.get_zlim())]
    hi = [max(ax.get_xlim()), max(ax.get_ylim()), max(ax.get_zlim())]
    assert np.all(P.min(axis=0) >= lo) and np.all(P.max(axis=0) <= hi)
    assert_equal_scale(ax)


@pytest.mark.parametrize("up", ["-y", "y", "z"])
@pytest.mark.parametrize("view", [(15.0, -30.0), (40.0, 70.0), (-20.0, 150.0)])
def test_equal_scale_holds_for_every_up_axis_and_view(rng, up, view):
    # a box much longer along one axis: a permuted aspect would show at once
    P = rng.uniform(size=(60, 3)) * [1.0, 3.0, 9.0]
    (ax,) = axes3d(plot_points_3d(P, up=up, view=view))
    assert_equal_scale(ax)


def _figures_of_the_kit(car):
    rng = np.random.default_rng(3)
    temple = rng.uniform(size=(288, 3)) * [1.2, 0.9, 0.8] + [-0.6, -0.4, 4.4]
    before = temple[:120] + rng.normal(scale=0.05, size=(120, 3))
    video = car_video(car, -90.0)
    video[8:, [0, 4, 9]] = np.nan
    return {
        "temple": plot_points_3d(temple, title="temple"),
        "bundle adjustment": plot_points_3d([before, temple[:120]], labels=["before", "after"],
                                            title="BA", layout="side_by_side"),
        "one car": plot_3d_keypoint(video[0], title="one car"),
        "car video": plot_3d_keypoint_frames(video, title="the car over 10 frames"),
    }


@pytest.mark.parametrize("name", ["temple", "bundle adjustment", "one car", "car video"])
def test_every_kit_figure_is_equal_scale_with_few_readable_ticks(car, name):
    from starter.figures import crowded_labels

    fig = _figures_of_the_kit(car)[name]
    for ax in axes3d(fig):
        assert_equal_scale(ax)
        for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
            lo, hi = sorted(axis.get_view_interval())
            shown = [t for t in axis.get_majorticklocs() if lo <= t <= hi]
            assert 1 <= len(shown) <= 6, f"{axis.axis_name}: {shown}"
            assert "(" in axis.label.get_text(), "axis titles state their convention"
    assert crowded_labels(fig.matplotlib, pad=0.0) == []
    # nothing written outside the picture: axis titles, tick labels and the legend
    fig.matplotlib.draw_without_rendering()
    renderer = fig.matplotlib._get_renderer()
    canvas = fig.matplotlib.bbox
    texts = [ax_.label for ax in axes3d(fig) for ax_ in (ax.xaxis, ax.yaxis, ax.zaxis)]
    texts += [lg for lg in fig.matplotlib.legends]
    for t in texts:
        box = t.get_window_extent(renderer)
        assert box.x0 >= canvas.x0 - 1 and box.x1 <= canvas.x1 + 1, (name, box)
        assert box.y0 >= canvas.y0 - 1 and box.y1 <= canvas.y1 + 1, (name, box)
    layout = fig.plotly_json()["layout"]
    for key in [k for k in layout if k.startswith("scene")]:
        assert layout[key]["aspectmode"] == "data"
        assert all(layout[key][a]["nticks"] <= 6 for a in ("xaxis", "yaxis", "zaxis"))


def test_crowded_labels_finds_labels_on_top_of_each_other():
    from matplotlib.ticker import MaxNLocator

    from starter.figures import crowded_labels

    # seen almost end-on, an axis with many ticks prints them on top of each other
    fig = plot_points_3d(np.random.default_rng(0).uniform(size=(20, 3)), view=(2.0, 1.0))
    (ax,) = axes3d(fig)
    ax.zaxis.set_major_locator(MaxNLocator(20))
    assert any(a is ax.zaxis and b is ax.zaxis for a, _, b, _ in crowded_labels(fig.matplotlib))


@pytest.mark.parametrize("heading", [-90.0, 0.0, 60.0, 135.0, 200.0])
def test_car_video_view_shows_the_path_across_the_ground_from_above(car, heading):
    video = car_video(car, heading)
    fig = plot_3d_keypoint_frames(video)
    (ax,) = axes3d(fig)
    J = screen_jacobian(ax)
    scale = np.linalg.norm(J[0]) if np.linalg.norm(J[0]) > 0 else 1.0
    scale = np.sqrt((J ** 2).sum() / 2)  # the common scale: each screen axis has length `scale`
    # looking down on the ground (X-Z plane): its unit square keeps sin(elevation) of its area
    ground = abs(np.linalg.det(J[[0, 2]])) / scale ** 2
    assert np.sin(np.radians(25)) < ground < np.sin(np.radians(75)), ground
    assert J[1, 1] < 0, "-Y (up) must point up the picture"
    # the cars' centres run from left to right across a good part of the picture
    centres = to_screen(ax, np.nanmean(video, axis=1))
    bbox = ax.bbox
    assert centres[-1, 0] > centres[0, 0]
    assert np.ptp(centres[:, 0]) > 0.4 * bbox.width
    # and the whole video is not flattened into a line: it fills a third of the height
    pts = video.reshape(-1, 3)
    assert np.ptp(to_screen(ax, pts)[:, 1]) > 0.3 * bbox.height
    # the plotly camera looks from the same side
    eye = fig.plotly_json()["layout"]["scene"]["camera"]["eye"]
    assert eye["y"] < 0, "plotly's eye is above the ground (-Y up)"


def test_car_view_without_motion_uses_the_car_axis(car):
    from starter.keypoints import car_view

    still = car_video(car, 0.0, T=1)[0]
    assert car_view([still, still]) == car_view([still])
    np.testing.assert_allclose(car_view([still]), car_view(car_video(car, 0.0, T=2)), atol=2.0)
    assert car_view([still * [-1.0, 1.0, -1.0]]) != car_view([still])


def test_flat_point_set_still_gets_a_finite_aspect(rng):
    P = np.column_stack([rng.normal(size=30), rng.normal(size=30), np.full(30, 2.0)])
    (ax,) = axes3d(plot_points_3d(P))
    assert np.all(np.isfinite(ax.get_box_aspect())) and np.all(np.asarray(ax.get_box_aspect()) > 0)


def test_car_skeleton_edges_are_drawn_as_lines(car):
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    fig = plot_3d_keypoint(car)
    (lines,) = traces(fig, "lines")
    expected = np.array([[car[i], car[j]] for i, j in CAR_SKELETON])
    assert same_segments(segments_of(lines), expected)
    fig.to_png()  # drawing projects the 3D segments, which get_segments then lists
    (ax,) = axes3d(fig)
    (col,) = [c for c in ax.collections if isinstance(c, Line3DCollection)]
    assert len(col.get_segments()) == len(CAR_SKELETON)
    (markers,) = traces(fig, "markers")
    assert markers["text"][0] == "wheel front-left"


def test_nan_keypoints_and_their_edges_are_skipped(car):
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Path3DCollection

    P = car.copy()
    P[[3, 8]] = np.nan
    fig = plot_3d_keypoint(P)
    (markers,) = traces(fig, "markers")
    np.testing.assert_allclose(xyz(markers), np.delete(car, [3, 8], axis=0))
    kept = [(i, j) for i, j in CAR_SKELETON if not {i, j} & {3, 8}]
    assert 0 < len(kept) < len(CAR_SKELETON)
    (lines,) = traces(fig, "lines")
    segs = segments_of(lines)
    assert np.isfinite(segs).all()
    assert same_segments(segs, np.array([[car[i], car[j]] for i, j in kept]))
    fig.to_png()
    (ax,) = axes3d(fig)
    (scatter,) = [c for c in ax.collections if isinstance(c, Path3DCollection)]
    assert len(scatter.get_offsets()) == 10
    (col,) = [c for c in ax.collections if isinstance(c, Line3DCollection)]
    assert len(col.get_segments()) == len(kept)


def test_before_and_after_side_by_side(rng):
    before = rng.normal(size=(30, 3))
    after = before + rng.normal(scale=0.05, size=before.shape)
    fig = plot_points_3d([before, after], labels=["before BA", "after BA"], layout="side_by_side")
    layout = fig.plotly_json()["layout"]
    assert layout["scene"]["aspectmode"] == layout["scene2"]["aspectmode"] == "data"
    scenes = [t.get("scene", "scene") for t in traces(fig, "markers")]
    assert scenes == ["scene", "scene2"]
    axes = axes3d(fig)
    assert [ax.get_title() for ax in axes] == ["before BA", "after BA"]


def test_overlay_gives_one_view_with_a_named_trace_per_set(rng):
    sets = [rng.normal(size=(10, 3)), rng.normal(size=(15, 3))]
    fig = plot_points_3d(sets, labels=["initial", "optimised"], colors=["red", "#00ff00"])
    markers = traces(fig, "markers")
    assert [t["name"] for t in markers] == ["initial", "optimised"]
    assert [t["marker"]["color"] for t in markers] == ["#ff0000", "#00ff00"]
    assert len(axes3d(fig)) == 1
    for t, P in zip(markers, sets):
        np.testing.assert_allclose(xyz(t), P)


def test_video_frames_one_colour_each_and_empty_frames_allowed(car, rng):
    frames = np.stack([car + [0.3 * t, 0.0, 0.0] for t in range(4)])
    frames[2] = np.nan
    frames[1, 5] = np.nan
    fig = plot_3d_keypoint_frames(frames)
    markers = traces(fig, "markers")
    assert [t["name"] for t in markers] == ["t=0", "t=1", "t=2", "t=3"]
    assert [len(plotly_array(t["x"])) for t in markers] == [12, 11, 0, 12]
    colors = [t["marker"]["color"] for t in markers]
    assert len(set(colors)) == 4
    lines = traces(fig, "lines")
    assert len(lines) == 3  # no edge at all for the empty frame
    for seg_trace in lines:
        assert np.isfinite(segments_of(seg_trace)).all()


# -- 2D keypoints -----------------------------------------------------------------------------

def _fake_detections(rng, width=200, height=150):
    xy = np.column_stack([rng.uniform(0, width - 1, 12), rng.uniform(0, height - 1, 12)])
    conf = rng.permutation(np.arange(1, 13) * 100)
    return np.column_stack([xy, conf]), (height, width)


@pytest.mark.parametrize("thres", [0, 600, 650, 1200])
def test_visualize_keypoints_keeps_confidence_strictly_above_threshold(rng, thres):
    from matplotlib.collections import PathCollection

    pts, (h, w) = _fake_detections(rng)
    img = (rng.random((h, w, 3)) * 255).astype(np.uint8)
    ax = Figure().subplots()
    assert visualize_keypoints(img, pts, thres, ax=ax) is ax
    keep = pts[:, 2] > thres
    (scatter,) = [c for c in ax.collections if isinstance(c, PathCollection)]
    np.testing.assert_allclose(np.asarray(scatter.get_offsets()).reshape(-1, 2), pts[keep, :2])
    drawn = [ln.get_xydata() for ln in ax.lines]
    expected = [pts[[i, j], :2] for i, j in CAR_SKELETON if keep[i] and keep[j]]
    assert len(drawn) == len(expected)
    for a, b in zip(drawn, expected):
        np.testing.assert_allclose(a, b)


def test_visualize_keypoints_makes_its_own_figure_for_a_float_grey_image(rng):
    import matplotlib.pyplot as plt

    pts, (h, w) = _fake_detections(rng)
    ax = visualize_keypoints(rng.random((h, w)), pts, 500)
    try:
        assert ax.figure in [plt.figure(n) for n in plt.get_fignums()]
        assert ax.get_xlim() == (-0.5, w - 0.5)
    finally:
        plt.close(ax.figure)


@pytest.mark.official
def test_visualize_keypoints_on_the_official_car(course_data):
    from matplotlib.collections import PathCollection

    frame = np.load(course_data / "q6" / "time0.npz")
    img = matplotlib.image.imread(course_data / "q6" / "cam1_time0.jpg")
    ax = visualize_keypoints(img, frame["pts1"], 300, ax=Figure().subplots())
    (scatter,) = [c for c in ax.collections if isinstance(c, PathCollection)]
    assert len(scatter.get_offsets()) == int((frame["pts1"][:, 2] > 300).sum())


# -- bad input --------------------------------------------------------------------------------

_P = np.random.default_rng(5).normal(size=(12, 3))
_IMG = np.zeros((20, 30, 3), np.uint8)
_PTS = np.column_stack([np.random.default_rng(6).uniform(0, 19, (12, 2)), np.full(12, 500.0)])
BAD_CALLS = {
    "points as 2D": ("points", lambda: plot_points_3d(np.zeros((5, 2)))),
    "points None": ("points", lambda: plot_points_3d(None)),
    "points all NaN": ("points", lambda: plot_points_3d(np.full((4, 3), np.nan))),
    "points inf": ("points", lambda: plot_points_3d(np.array([[0.0, 0.0, np.inf]]))),
    "second set 4 columns": ("points[1]", lambda: plot_points_3d([_P, np.zeros((3, 4))])),
    "labels count": ("labels", lambda: plot_points_3d([_P, _P], labels=["only one"])),
    "edge out of range": ("edges", lambda: plot_points_3d(_P, edges=[(0, 12)])),
    "edges not integers": ("edges", lambda: plot_points_3d(_P, edges=[(0.5, 1.0)])),
    "layout": ("layout", lambda: plot_points_3d(_P, layout="grid")),
    "colour name": ("colors", lambda: plot_points_3d(_P, colors=["not-a-colour"])),
    "up axis": ("up", lambda: plot_points_3d(_P, up="x")),
    "hover_text count": ("hover_text", lambda: plot_points_3d(_P, hover_text=["a", "b"])),
    "P 2D": ("P", lambda: plot_3d_keypoint(_P[:, :2])),
    "P too few for skeleton": ("P", lambda: plot_3d_keypoint(_P[:5])),
    "frames single frame": ("frames", lambda: plot_3d_keypoint_frames(_P)),
    "frames ragged": ("frames", lambda: plot_3d_keypoint_frames([_P, _P[:11]])),
    "cmap": ("cmap", lambda: plot_3d_keypoint_frames([_P, _P], cmap="nope")),
    "image 0-255 float": ("image", lambda: visualize_keypoints(_IMG * 1.0 + 7, _PTS, 100,
                                                               ax=Figure().subplots())),
    "image 1D": ("image", lambda: visualize_keypoints(np.zeros((20,)), _PTS, 100)),
    "pts without confidence": ("pts", lambda: visualize_keypoints(_IMG, _PTS[:, :2], 100)),
    "pts too few": ("pts", lambda: visualize_keypoints(_IMG, _PTS[:6], 100)),
    "Thres text": ("Thres", lambda: visualize_keypoints(_IMG, _PTS, "high")),
    "Thres NaN": ("Thres", lambda: visualize_keypoints(_IMG, _PTS, float("nan"))),
}


@pytest.mark.parametrize("case", list(BAD_CALLS))
def test_bad_input_raises_value_error_naming_the_argument(case):
    name, call = BAD_CALLS[case]
    with pytest.raises(ValueError) as info:
        call()
    assert str(info.value).startswith(name + ":"), str(info.value)


def test_figures_never_touch_pyplot(rng):
    import matplotlib.pyplot as plt

    before = plt.get_fignums()
    plot_points_3d(rng.normal(size=(5, 3))).to_png()
    assert plt.get_fignums() == before
    assert "kaleido" not in sys.modules


def test_show_outside_a_notebook_prints_the_text_form(rng, capsys):
    plot_points_3d(rng.normal(size=(5, 3)), title="t").show()
    assert "Figure3D" in capsys.readouterr().out


def test_default_colours_differ_between_sets(rng):
    sets = [rng.normal(size=(3, 3)) for _ in range(5)]
    colors = [t["marker"]["color"] for t in traces(plot_points_3d(sets), "markers")]
    assert all(a != b for a, b in itertools.combinations(colors, 2))
