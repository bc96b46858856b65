"""starter.interactive without a browser: line clipping, picks, matches, static and widget forms."""

from __future__ import annotations

import base64
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from core.geometry import epipolar_distances, skew
from core.paths import KIT_ROOT
from core.validate import DegenerateInputError
from starter.interactive import (
    EpipolarApp,
    EpipolarSession,
    displayEpipolarF,
    epipolar_line,
    epipolar_line_endpoints,
    epipolarMatchGUI,
)

W, H = 160, 120


@pytest.fixture
def F(rng):
    """F of two cameras looking at a W x H scene, x2^T F x1 = 0, at an arbitrary scale and sign.

    Camera 2 is camera 1 moved sideways and turned a little, so epipolar lines cross image 2.
    """
    from scenes.cameras import intrinsics, rotation_about

    K = intrinsics(100.0, W / 2, H / 2)
    R = rotation_about(rng.normal(size=3), 0.1)
    t = np.array([1.0, 0.2, 0.1]) + rng.normal(scale=0.05, size=3)
    E = skew(t) @ R
    return -37.0 * np.linalg.inv(K).T @ E @ np.linalg.inv(K)


@pytest.fixture
def images(rng):
    return rng.random((H, W)), (rng.random((H, W, 3)) * 255).astype(np.uint8)


def project_on_line(F, x1, y1):
    """A perfect matcher: the point of the epipolar line closest to (x1, y1)."""
    line = epipolar_line(F, x1, y1)
    p = np.array([x1, y1, 1.0])
    return p[:2] - line[:2] * (line @ p)


def perfect_match(im1, im2, F, x1, y1):
    """match_fn for the tests: always on the line."""
    return project_on_line(F, x1, y1)


def decode_png(data: bytes) -> np.ndarray:
    import io

    import matplotlib.image

    return matplotlib.image.imread(io.BytesIO(data), format="png")


def line_of(F, x1, y1):
    return np.asarray(F, float) @ [x1, y1, 1.0]


def off_line(F, x1, y1, x, y):
    """Distance in pixels of (x, y) in image 2 from the epipolar line of (x1, y1)."""
    return epipolar_distances(F, [(x1, y1)], [(x, y)])[0]


def image2_lines(fig):
    """The epipolar lines drawn in the right-hand axes: 2-point solid Line2D."""
    ax2 = fig.axes[1]
    return [ln for ln in ax2.lines if ln.get_linestyle() == "-" and len(ln.get_xdata()) == 2]


# -- pure geometry ----------------------------------------------------------------------------

def test_endpoints_lie_on_the_line_and_on_the_border(F, rng):
    for x1, y1 in rng.uniform([0, 0], [W - 1, H - 1], size=(50, 2)):
        ends = epipolar_line_endpoints(F, x1, y1, W, H)
        if ends is None:
            continue
        for x, y in ends:
            assert off_line(F, x1, y1, x, y) < 1e-9
            assert -1e-9 <= x <= W - 1 + 1e-9 and -1e-9 <= y <= H - 1 + 1e-9
            on_border = min(abs(x), abs(x - (W - 1)), abs(y), abs(y - (H - 1)))
            assert on_border < 1e-9
        assert np.linalg.norm(ends[0] - ends[1]) > 0


def test_a_typical_scene_crosses_image_2():
    # cameras side by side: lines nearly horizontal, through the middle of image 2
    K = np.array([[100.0, 0, W / 2], [0, 100.0, H / 2], [0, 0, 1]])
    E = skew([1.0, 0.05, 0.0]) @ np.eye(3)
    F = np.linalg.inv(K).T @ E @ np.linalg.inv(K)
    ends = epipolar_line_endpoints(F, 80, 60, W, H)
    assert ends is not None
    np.testing.assert_allclose(sorted(ends[:, 0]), [0, W - 1])


@pytest.mark.parametrize("line, expected", [
    ((0.0, 1.0, -5.0), [[0, 5], [W - 1, 5]]),          # y = 5
    ((1.0, 0.0, -7.0), [[7, 0], [7, H - 1]]),          # x = 7
    ((1.0, -1.0, 0.0), [[0, 0], [H - 1, H - 1]]),      # the diagonal, through a corner
])
def test_axis_parallel_and_corner_lines(line, expected):
    # F that sends every point to the same line: rank 1, enough for the clipping
    F = np.outer(line, [0.0, 0.0, 1.0])
    ends = epipolar_line_endpoints(F, 3, 4, W, H)
    assert sorted(map(tuple, np.round(ends, 9))) == sorted(map(tuple, np.asarray(expected, float)))


@pytest.mark.parametrize("line", [(1.0, 0.0, 10.0), (1.0, 1.0, 1.0), (1.0, 1.0, 0.0)])
def test_a_line_that_misses_or_only_touches_a_corner_gives_none(line):
    F = np.outer(line, [0.0, 0.0, 1.0])
    assert epipolar_line_endpoints(F, 3, 4, W, H) is None


def test_the_epipole_has_no_line(F):
    e1 = np.linalg.svd(F)[2][-1]
    with pytest.raises(DegenerateInputError, match="epipole"):
        epipolar_line(F, e1[0] / e1[2], e1[1] / e1[2])


def test_epipolar_line_is_normalised_and_scale_free(F):
    a = epipolar_line(F, 10, 20)
    b = epipolar_line(-5.0 * F, 10, 20)
    assert np.hypot(a[0], a[1]) == pytest.approx(1.0)
    assert np.allclose(a, b) or np.allclose(a, -b)


# -- picks and matches ------------------------------------------------------------------------

def test_a_pick_gives_the_line_F_x1_and_calls_the_matcher_with_the_pixel(F, images):
    I1, I2 = images
    calls = []

    def match(im1, im2, F_, x1, y1):
        calls.append((im1, im2, F_, x1, y1))
        return project_on_line(F_, x1, y1)

    session = EpipolarSession(I1, I2, F, match)
    pick = session.pick(37, 81)
    ((im1, im2, F_, x1, y1),) = calls
    assert im1 is I1 and im2 is I2 and F_ is F
    assert (x1, y1) == (37, 81) and all(isinstance(v, int) for v in (x1, y1))
    line = line_of(F, 37, 81)
    assert np.allclose(np.cross(pick.line, line), 0, atol=1e-9 * np.linalg.norm(line))
    for x, y in pick.endpoints:
        assert off_line(F, 37, 81, x, y) < 1e-9
    np.testing.assert_allclose(pick.match, project_on_line(F, 37, 81))
    assert pick.distance < 1e-9 and pick.warning is None

    fig = session.figure()
    (drawn,) = image2_lines(fig)
    for x, y in drawn.get_xydata():
        assert off_line(F, 37, 81, x, y) < 1e-9
    match_markers = [ln for ln in fig.axes[1].lines if ln.get_marker() == "o"]
    np.testing.assert_allclose(match_markers[0].get_xydata()[0], pick.match)


def test_a_fractional_pick_is_rounded_to_the_pixel_the_matcher_gets(F, images):
    seen = []
    session = EpipolarSession(*images, F, lambda a, b, f, x, y: seen.append((x, y)) or (x, y))
    pick = session.pick(10.4, 19.6)
    assert seen == [(10, 20)] and (pick.x1, pick.y1) == (10, 20)


def test_static_form_with_five_points_draws_five_lines_in_five_colours(F, images):
    I1, I2 = images
    pts = np.array([[10, 10], [150, 20], [80, 60], [20, 110], [140, 100]])
    session = epipolarMatchGUI(I1, I2, F, perfect_match, points=pts)
    assert len(session.picks) == 5
    fig = session.figure()
    lines = image2_lines(fig)
    assert len(lines) == 5
    for ln, (x1, y1) in zip(lines, pts):
        for x, y in ln.get_xydata():
            assert off_line(F, x1, y1, x, y) < 1e-9
    assert len({ln.get_color() for ln in lines}) == 5
    # same colour for the point in image 1 and its line in image 2
    rings1 = [ln for ln in fig.axes[0].lines if ln.get_marker() == "o"]
    assert [r.get_markeredgecolor() for r in rings1] == [ln.get_color() for ln in lines]
    np.testing.assert_allclose(session.points(), pts)
    assert session.matches().shape == (5, 2)


def test_display_epipolar_f_without_matcher(F, images):
    session = displayEpipolarF(*images, F, points=[[5, 5], [100, 50], [60, 100]])
    assert len(image2_lines(session.figure())) == 3
    assert all(p.match is None for p in session.picks)
    assert np.isnan(session.matches()).all()
    png = session.to_png()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


def test_display_epipolar_f_draws_the_known_matches_on_their_lines(F, images):
    pts = np.array([[10, 10], [80, 60], [140, 100]])
    known = np.array([project_on_line(F, x, y) for x, y in pts])
    session = displayEpipolarF(*images, F, points=pts, matches=known)
    np.testing.assert_allclose(session.matches(), known)
    fig = session.figure()
    lines = image2_lines(fig)
    rings2 = [ln for ln in fig.axes[1].lines if ln.get_marker() == "o"]
    # Each match is ringed in image 2 in its line's colour, and lies on that line.
    assert [r.get_markeredgecolor() for r in rings2] == [ln.get_color() for ln in lines]
    for ring, (x1, y1) in zip(rings2, pts):
        assert off_line(F, x1, y1, *ring.get_xydata()[0]) < 1e-9
    assert session.match_fn is None  # a later pick (the picker) has no known match
    with pytest.raises(ValueError, match="matches: expected one match per point"):
        displayEpipolarF(*images, F, points=pts, matches=known[:2])
    with pytest.raises(ValueError, match="matches: expected them with points"):
        displayEpipolarF(*images, F, matches=known)


def test_a_match_far_from_the_line_warns(F, images):
    def sloppy(im1, im2, F_, x1, y1):
        x2, y2 = project_on_line(F_, x1, y1)
        line = epipolar_line(F_, x1, y1)
        return x2 + 6 * line[0], y2 + 6 * line[1]  # 6 px off the line

    with pytest.warns(UserWarning, match="px from the epipolar line"):
        session = epipolarMatchGUI(*images, F, sloppy, points=[[40, 40]])
    assert session.picks[0].distance == pytest.approx(6.0)
    assert "WARNING" in session.picks[0].describe()


def test_matcher_returning_garbage_is_named(F, images):
    session = EpipolarSession(*images, F, lambda *a: "somewhere")
    with pytest.raises(ValueError, match="^match_fn:"):
        session.pick(3, 3)


@pytest.mark.parametrize("call, name", [
    (lambda I1, I2, F: EpipolarSession(I1, I2, F[:, :2]), "F"),
    (lambda I1, I2, F: EpipolarSession(I1 * 255 + 2, I2, F), "I1"),
    (lambda I1, I2, F: EpipolarSession(I1, np.zeros((5,)), F), "I2"),
    (lambda I1, I2, F: EpipolarSession(I1, I2, F, match_fn=3), "match_fn"),
    (lambda I1, I2, F: EpipolarSession(I1, I2, F).pick(W + 3, 5), "x1"),
    (lambda I1, I2, F: EpipolarSession(I1, I2, F).pick(5, -2), "y1"),
    (lambda I1, I2, F: EpipolarSession(I1, I2, F).pick(np.nan, 5), "x1"),
    (lambda I1, I2, F: epipolarMatchGUI(I1, I2, F, None), "match_fn"),
    (lambda I1, I2, F: displayEpipolarF(I1, I2, F, points=[1, 2, 3]), "points"),
    (lambda I1, I2, F: epipolar_line_endpoints(F, 1, 1, 0, 10), "width"),
])
def test_bad_input_names_the_argument(F, images, call, name):
    with pytest.raises(ValueError) as info:
        call(*images, F)
    assert str(info.value).startswith(name + ":"), str(info.value)


def test_grey_single_channel_and_colour_images_are_accepted(F, rng):
    grey1 = rng.random((H, W, 1))
    colour = rng.random((H, W, 3))
    session = displayEpipolarF(grey1, colour, F, points=[[50, 50]])
    assert len(image2_lines(session.figure())) == 1


# -- the widget front end, driven from Python -------------------------------------------------

def _figure_widget_app(session):
    pytest.importorskip("ipywidgets")
    try:
        return EpipolarApp(session, use_plotly=True)
    except ValueError as exc:
        pytest.skip(f"plotly FigureWidget unavailable: {exc}")


def test_a_simulated_click_draws_the_line_and_match_in_the_widget(F, images):
    session = EpipolarSession(*images, F, perfect_match)
    app = _figure_widget_app(session)
    fw = app.figure_widget
    assert len(fw.layout.shapes) == 0
    app._on_click(fw.data[0], SimpleNamespace(xs=[70], ys=[33], point_inds=[0]), None)
    app._on_click(fw.data[0], SimpleNamespace(xs=[12], ys=[100], point_inds=[0]), None)
    assert [(p.x1, p.y1) for p in session.picks] == [(70, 33), (12, 100)]
    assert len(fw.layout.shapes) == 2
    for shape, (x1, y1) in zip(fw.layout.shapes, [(70, 33), (12, 100)]):
        assert (shape.xref, shape.yref) == ("x2", "y2")
        for x, y in [(shape.x0, shape.y0), (shape.x1, shape.y1)]:
            assert off_line(F, x1, y1, x, y) < 1e-6
    assert list(fw.data[2].x) == [70, 12] and list(fw.data[2].y) == [33, 100]
    np.testing.assert_allclose(np.column_stack([fw.data[3].x, fw.data[3].y]), session.matches())
    assert 'data-x1="12"' in app.status.value and 'data-y1="100"' in app.status.value
    assert (app.x_box.value, app.y_box.value) == (12, 100)


def test_a_large_image_is_subsampled_for_the_browser_only(F, rng):
    big = rng.random((1500, 2000))
    app = _figure_widget_app(EpipolarSession(big, big, F))
    image1 = app.figure_widget.data[0]
    assert (image1.dx, image1.dy) == (2, 2)
    app._on_click(image1, SimpleNamespace(xs=[1998], ys=[1498], point_inds=[0]), None)
    assert (app.session.picks[0].x1, app.session.picks[0].y1) == (1998, 1498)


def test_number_boxes_and_button_work_without_plotly(F, images):
    pytest.importorskip("ipywidgets")
    session = EpipolarSession(*images, F, perfect_match)
    app = EpipolarApp(session, use_plotly=False)
    assert app.figure_widget is None
    app.x_box.value, app.y_box.value = 44, 55
    app.pick_button.click()
    assert [(p.x1, p.y1) for p in session.picks] == [(44, 55)]
    assert 'data-x1="44"' in app.status.value
    app.clear_button.click()
    assert session.picks == [] and "0 picks" in app.status.value


def test_a_failing_matcher_shows_in_the_status_line_instead_of_raising(F, images):
    pytest.importorskip("ipywidgets")

    def broken(*args):
        raise IndexError("window out of bounds")

    app = EpipolarApp(EpipolarSession(*images, F, broken), use_plotly=False)
    assert app.pick(5, 5) is None
    assert "IndexError: window out of bounds" in app.status.value
    assert app.session.picks == []


def test_interactive_outside_a_kernel_falls_back_to_static_with_a_warning(F, images):
    with pytest.warns(UserWarning, match="Jupyter kernel"):
        session = displayEpipolarF(*images, F, points=[[3, 3]], interactive=True)
    assert session.app is None and len(session.picks) == 1


@pytest.mark.slow
def test_in_a_kernel_the_saved_notebook_keeps_the_latest_static_png(tmp_path):
    """A pick made after the cell ran (as a click would) updates the PNG output in place."""
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipywidgets")
    setup = (f"import sys; sys.path.insert(0, {str(KIT_ROOT)!r})\n"
             "import numpy as np\n"
             "from starter.interactive import EpipolarApp, EpipolarSession, displayEpipolarF\n"
             "rng = np.random.default_rng(3)\n"
             "I1, I2 = rng.random((60, 80)), rng.random((60, 80))\n"
             "F = np.array([[0, -1e-3, 0.05], [1e-3, 0, -0.2], [-0.06, 0.21, 0.3]])\n"
             # the number-box front end: the same snapshot path as the plotly one, and no
             # FigureWidget to load in the kernel (the browser test covers that one)
             "s = EpipolarSession(I1, I2, F, lambda a, b, F, x, y: (x, y))\n"
             "s.app = EpipolarApp(s, use_plotly=False)\n"
             "s.app.display()")
    cells = [setup, "s.app.pick(20, 30)\ns.app.pick(60, 10);",
             "displayEpipolarF(I1, I2, F, points=[[1, 1], [40, 40]]);"]
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(c) for c in cells])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        nbclient.NotebookClient(nb, timeout=120, kernel_name="python3",
                                resources={"metadata": {"path": str(tmp_path)}}).execute()
    widget_out, png_out = nb.cells[0].outputs
    assert "application/vnd.jupyter.widget-view+json" in widget_out["data"]
    assert "image/png" in png_out["data"]
    # the first cell's PNG is now the state after the two picks, not the empty one
    rng = np.random.default_rng(3)
    I1, I2 = rng.random((60, 80)), rng.random((60, 80))
    F = np.array([[0, -1e-3, 0.05], [1e-3, 0, -0.2], [-0.06, 0.21, 0.3]])
    local = EpipolarSession(I1, I2, F, lambda a, b, F, x, y: (x, y))
    empty = decode_png(local.to_png())
    local.pick(20, 30)
    local.pick(60, 10)
    saved = decode_png(base64.b64decode(png_out["data"]["image/png"]))
    assert saved.shape == empty.shape
    assert np.abs(saved - decode_png(local.to_png())).max() < 1e-6
    assert np.abs(saved - empty).max() > 0.1
    assert nb.cells[1].outputs == []
    (static,) = nb.cells[2].outputs
    assert set(static["data"]) >= {"image/png"}
    assert not any("widget" in k for k in static["data"])
