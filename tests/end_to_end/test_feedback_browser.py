"""The feedback page and Gradescope's picture tests, opened in a real browser (headless Chromium).

What only a browser shows: every ``<img>`` decodes (``naturalWidth > 0``) and has an alt text, no
request leaves the file (the page is offline), and a student's hostile text (``<script>``, a
spreadsheet formula, terminal escapes, in an exception's message and in the submission's name)
is shown as text and runs nothing.  Gradescope's results.json is read back from disk and each
test's html ``output`` put in a page as it is (no sanitiser: the worst case).

Needs Chromium (``apt-get install chromium``, or $HW4_CHROMIUM) and playwright (its browser
download is not used); skips, saying what is missing, otherwise.
"""

from __future__ import annotations

import json

import pytest

from autograder.feedback import page as feedback_page
from autograder.channels.gradescope import pictures as gradescope_pictures
from autograder.feedback import pictures as step
from autograder.hidden.plugin import LocalStudent
import picture_standin
from browser import CHROMIUM_ARGS, chromium_path
from gradescope_like import build_test_bundle
from picture_cases import HOSTILE, good_triangulate, hostile_eightpoint, result_with

pytestmark = [pytest.mark.browser, pytest.mark.slow]


@pytest.fixture(autouse=True)
def standin(monkeypatch):
    monkeypatch.setattr(step, "contract", lambda: picture_standin)


def _raw():
    return {"Q2": step.picture_record(LocalStudent({"eightpoint": hostile_eightpoint}), "Q2"),
            "Q3.2": step.picture_record(LocalStudent({"triangulate": good_triangulate}), "Q3.2")}


@pytest.fixture(scope="module")
def browser():
    path = chromium_path()
    if path is None:
        pytest.skip("no Chromium found (apt-get install chromium, or set HW4_CHROMIUM)")
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright not installed (pip install playwright)")
    with sync_api.sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=path, args=CHROMIUM_ARGS)
        try:
            yield b
        finally:
            b.close()


def open_page(browser, path) -> dict:
    """What the page shows: its images, the requests it made, its text, and whether a script ran."""
    page = browser.new_page()
    requests = []
    page.on("request", lambda r: requests.append(r.url))
    try:
        page.goto(path.as_uri())
        page.wait_for_load_state("load")
        images = page.evaluate("""() => Array.from(document.images).map(i => ({
            complete: i.complete, width: i.naturalWidth, alt: i.getAttribute('alt') || ''}))""")
        return {"images": images, "requests": requests, "text": page.inner_text("body"),
                "pwned": page.evaluate("() => window.pwned === 1")}
    finally:
        page.close()


def check_shown(shown: dict, n_images: int) -> None:
    assert len(shown["images"]) == n_images
    for img in shown["images"]:
        assert img["complete"] and img["width"] > 0, "an image did not decode"
        assert img["alt"].strip(), "an image has no alt text"
    assert all(u.startswith(("file:", "data:")) for u in shown["requests"]), shown["requests"]
    assert not shown["pwned"], "the student's script ran"
    assert "<script>window.pwned=1</script>" in shown["text"], "the hostile text is not shown as text"
    assert "\x1b" not in shown["text"] and "\u202e" not in shown["text"]


def test_feedback_page_in_a_browser(browser, tmp_path):
    result = result_with("eightpoint raised ValueError: " + HOSTILE)  # student id: the hostile text too
    path = feedback_page.write(tmp_path / "student", result, step.figures_of(_raw()))
    shown = open_page(browser, path)
    check_shown(shown, 1)
    assert "figure not drawn: eightpoint raised ValueError" in shown["text"]
    assert "=cmd|" in shown["text"]


@pytest.mark.parametrize("layout", [None, {"checks": "visible"}])
def test_gradescope_results_json_pictures_in_a_browser(browser, tmp_path, layout):
    result = result_with("failed: " + HOSTILE)
    data = gradescope_pictures.add_pictures(result.to_gradescope(visibility=layout), result, _raw())
    (tmp_path / "results.json").write_text(json.dumps(data, allow_nan=False))
    tests = json.loads((tmp_path / "results.json").read_text())["tests"]
    html = [t["output"] for t in tests if t.get("output_format") == "html"]
    assert len(html) == 2
    page = tmp_path / "gradescope_like.html"
    page.write_text("<!DOCTYPE html><html><head><meta charset='utf-8'></head><body>"
                    + "".join(f"<section>{h}</section>" for h in html) + "</body></html>")
    shown = open_page(browser, page)
    check_shown(shown, 1)


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    """A Gradescope bundle built with the pictures (the default)."""
    return build_test_bundle(tmp_path_factory.mktemp("bundle"))


def test_run_autograder_results_json_carries_the_pictures(browser, bundle, tmp_path):
    # The real channel: the bundle's run_autograder grades the answer key, results.json is read
    # back and every html output is opened as it stands.
    pytest.importorskip("starter.checks.pictures", reason="the pictures module is not in this kit yet")
    from gradescope_like import unpack
    from gradescope_like import KEY, assert_valid_results, put, run_autograder

    ag = unpack(bundle, tmp_path)
    put(ag, *sorted(KEY.glob("*.ipynb")))
    data = run_autograder(ag)
    assert_valid_results(data)
    pictures = [t for t in data["tests"] if " picture: " in t["name"]]
    assert pictures and all(t["output_format"] == "html" and "score" not in t for t in pictures)
    assert {t["visibility"] for t in pictures} == {"after_published"}  # the checks' default group
    page = tmp_path / "gradescope_like.html"
    page.write_text("<!DOCTYPE html><html><head><meta charset='utf-8'></head><body>"
                    + "".join(f"<section>{t['output']}</section>" for t in pictures) + "</body></html>")
    shown = open_page(browser, page)
    assert len(shown["images"]) == sum('<img ' in t["output"] for t in pictures) >= 1
    for img in shown["images"]:
        assert img["complete"] and img["width"] > 0 and img["alt"].strip()
    assert all(u.startswith(("file:", "data:")) for u in shown["requests"])
