"""Every scene the kit shows or grades on lies inside the homework's envelope (scenes.envelope).

Scenes: the default data's (scenes.defaults.default_temple), the public self-checks' (the generated
temple and its K1 != K2 pair of starter/checks/_scenes.py), and the hidden draws of
``make_scenes`` under ``quick_config`` and the default ``GradingConfig`` for the secret sweep's
secrets (CI's 2, the release sweep's 20: tests/support/breadth.py; their temples, the temples drawn for
matching that Q4.1 and Q4.2 use, and the K1 != K2 pair the hidden Q3.1 and Q3.2 use).  Only what
the checks need is made: the hidden draws without the default data (``fixed=False``), in two
forked processes.

Then the two hand-in habits that scenes outside the envelope failed: E / E[2, 2] (a public and a
hidden Q3.1 input had E[2, 2] = 0 up to rounding) and a 101 x 101 matching window cut without
padding (templeCoords came within 10 px of the border).
"""

from __future__ import annotations

import breadth
import numpy as np
import parallel
import pytest

from autograder.inputs.config import GradingConfig, quick_config
from scenes import envelope

SECRETS = breadth.secrets("sweep-secret")   # tests/end_to_end/test_secret_sweep.py's
CONFIGS = {"quick_config": quick_config, "GradingConfig": GradingConfig}


def _draw_problems(item) -> list[str]:
    """What of the hidden draw of (config name, secret) is outside the envelope (module level: forked)."""
    from autograder.inputs.correspondence import matching_scenes
    from autograder.inputs.scenes import make_scenes

    name, secret = item
    config = CONFIGS[name](secret=secret)
    scenes = make_scenes(config, fixed=False)
    where = f"{name}, {secret}"
    out = []
    for case, spec in zip(scenes.hidden, config.temples):
        out += envelope.outside_envelope(case.scene, noise_px=spec.noise_px, label=f"{where}, {case.label}")
    # Q4.1 and Q4.2 are judged on temples of their own, drawn for matching.
    for k, (case, spec) in enumerate(zip(matching_scenes(scenes), config.temples), start=1):
        out += envelope.outside_envelope(case.scene, noise_px=spec.noise_px, label=f"{where}, matching temple {k}")
    tv = scenes.two_view
    out += envelope.pair_outside_envelope(tv.K1, tv.K2, tv.M2, f"{where}, the K1 != K2 pair")
    return out


@pytest.fixture(scope="module")
def hidden_problems() -> list[str]:
    items = [(name, s) for name in CONFIGS for s in SECRETS]
    return [p for found in parallel.fork_map(_draw_problems, items) for p in found]


# ----------------------------------------------------------------------------- the envelope itself

def test_the_envelope_names_what_is_outside():
    # A fixating pair: camera 2 swung about the x axis through a point on camera 1's optical axis.
    from scenes.cameras import intrinsics, rotation_about

    K = intrinsics(1520.0, 302.0, 247.0)
    Q = rotation_about([1, 0, 0], np.deg2rad(11.0))
    pivot = np.array([0.0, 0.0, 7.0])
    M2 = np.hstack([Q.T, (-Q.T @ (pivot - Q @ pivot))[:, None]])
    found = envelope.pair_outside_envelope(K, K, M2, "fixating")
    assert any("|E[2,2]|/|E|" in p for p in found) and all(p.startswith("fixating") for p in found)
    toe = rotation_about([0, 1, 0], np.deg2rad(0.04))
    M2[:, :3] = toe @ M2[:, :3]
    M2[:, 3] = toe @ M2[:, 3]
    assert envelope.pair_outside_envelope(K, K, M2) == []
    with pytest.raises(ValueError, match="A: expected"):
        envelope.corner_ratio(np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"A: expected a \(3, 3\)"):
        envelope.corner_ratio(np.ones((2, 2)))


@pytest.mark.official
def test_the_official_data_is_inside_the_envelope(official_temple, course_data):
    # The bounds are derived from the official pair: it must satisfy them.
    from PIL import Image

    from solutions import eightpoint

    d = official_temple
    F = eightpoint(d.pts1, d.pts2, d.M)
    assert envelope.corner_ratio(d.K2.T @ F @ d.K1) >= envelope.MIN_E33
    assert envelope.corner_ratio(F) >= envelope.MIN_F33
    disp = d.pts2 - d.pts1
    assert envelope.DISPARITY_X[0] <= disp[:, 0].min() and disp[:, 0].max() <= envelope.DISPARITY_X[1]
    assert envelope.DISPARITY_Y[0] <= disp[:, 1].min() and disp[:, 1].max() <= envelope.DISPARITY_Y[1]
    W, H = Image.open(course_data / "temple" / "im1.png").size
    assert envelope.WIDTH[0] <= W <= envelope.WIDTH[1] and envelope.HEIGHT[0] <= H <= envelope.HEIGHT[1]
    with np.load(course_data / "temple" / "templeCoords.npz") as c:
        xy = np.column_stack([c["x1"], c["y1"]]).astype(float)
    assert np.min(np.minimum(xy, [W - 1, H - 1] - xy)) >= envelope.BORDER_MARGIN


# ----------------------------------------------------------------------------- every scene inside

def test_the_default_data_scene_is_inside_the_envelope():
    from scenes.defaults import default_temple

    assert envelope.outside_envelope(default_temple(), noise_px=0.2, label="the default data") == []


def test_the_public_check_scenes_are_inside_the_envelope():
    from starter.checks._scenes import temple_scene, two_view

    assert envelope.outside_envelope(temple_scene(), label="the public temple") == []
    pair = two_view().pair
    assert envelope.pair_outside_envelope(pair.K1, pair.K2, pair.M2, "the public K1 != K2 pair") == []


@pytest.mark.slow
def test_every_hidden_draw_of_the_sweep_secrets_is_inside_the_envelope(hidden_problems):
    assert hidden_problems == []


# ----------------------------------------------------------------------------- the habits

def _essential_by_last_entry(F, K1, K2):
    """A correct essentialMatrix written with a common habit: normalised by its last entry."""
    E = np.asarray(K2).T @ np.asarray(F) @ np.asarray(K1)
    return E / E[2, 2]


def test_E_over_its_last_entry_passes_the_public_Q31_check():
    from starter.checks import essential as public
    from starter.checks._scenes import two_view

    pair = two_view().pair
    E = _essential_by_last_entry(pair.F, pair.K1, pair.K2)
    assert np.all(np.isfinite(E))
    assert envelope.division_gap(pair.K2.T @ pair.F @ pair.K1, pair.E) <= 1e-9
    report = public.check_essentialMatrix(_essential_by_last_entry, verbose=False)
    assert report.passed, report


@pytest.mark.slow
def test_E_over_its_last_entry_passes_the_hidden_Q31_test():
    import contextlib
    import io

    from autograder.inputs.build import build_hidden_inputs
    from autograder.hidden.plugin import HIDDEN_DIR, LocalStudent, run_here

    hidden = build_hidden_inputs(quick_config(secret=SECRETS[0]))
    with contextlib.redirect_stdout(io.StringIO()):
        result = run_here(LocalStudent({"essentialMatrix": _essential_by_last_entry}), hidden,
                          tests=[HIDDEN_DIR / "test_essential.py"], args=["--tb=no", "-p", "no:unraisableexception"])
    (q31,) = [q for q in result.questions if q.id == "Q3.1"]
    assert q31.max_score > 0 and q31.score == q31.max_score, [(t.name, t.score, t.feedback) for t in q31.tests]


_HALF = 50   # a 101 x 101 window


def _matcher_101(im1, im2, F, x1, y1, search=30):
    """A hand-in style matcher: 101 x 101 windows cut without padding (numpy then raises on a
    window that leaves the image), candidates the line's pixels within +-search rows whose window fits."""
    im1, im2 = np.asarray(im1, float), np.asarray(im2, float)
    H, W = im2.shape[:2]
    a, b, c = F @ np.array([x1, y1, 1.0])
    ys = np.arange(y1 - search, y1 + search + 1)
    xs = np.rint(-(b * ys + c) / a).astype(int)
    keep = (xs >= _HALF) & (xs < W - _HALF) & (ys >= _HALF) & (ys < H - _HALF)
    ref = im1[y1 - _HALF:y1 + _HALF + 1, x1 - _HALF:x1 + _HALF + 1]
    scores = [np.sum((im2[y - _HALF:y + _HALF + 1, x - _HALF:x + _HALF + 1] - ref) ** 2)
              for x, y in zip(xs[keep], ys[keep])]
    k = int(np.argmin(scores))
    return int(xs[keep][k]), int(ys[keep][k])


def _windows_fit(im, xy) -> bool:
    x, y = (int(round(v)) for v in xy)
    return im[max(y - _HALF, 0):y + _HALF + 1, max(x - _HALF, 0):x + _HALF + 1].shape[:2] == (101, 101) \
        and y - _HALF >= 0 and x - _HALF >= 0


@pytest.mark.slow  # makes the hidden scenes of a draw (about 4 s): the full tier's, as the sweep above
def test_a_101px_window_fits_around_every_chosen_point_of_the_hidden_draws():
    from autograder.inputs.correspondence import matching_scenes, prepare_correspondence
    from autograder.inputs.scenes import make_scenes

    scenes = make_scenes(quick_config(secret=SECRETS[0]))
    for case in prepare_correspondence(scenes).cases:
        for p1, p2 in zip(case.pts1, case.truth2):
            assert _windows_fit(case.im1, p1) and _windows_fit(case.im2, p2), (case.label, p1, p2)
        # The matcher itself runs on a few points of each scene: no window leaves the image.
        for x, y in case.pts1[:4].astype(int):
            _matcher_101(case.im1, case.im2, case.F, int(x), int(y))
    for tc in scenes.temple_cases(official=False):
        s = tc.scene
        for p1, p2 in zip(np.column_stack([s.x1, s.y1]), s.x2_true):
            assert _windows_fit(s.im1, p1) and _windows_fit(s.im2, p2), (tc.label, p1, p2)
