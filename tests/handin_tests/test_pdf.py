"""The Gradescope PDF: built from small notebooks that mimic the kit's, then read back.

The notebooks hold what breaks nbconvert's own PDF routes: question headings, a 300-character
code line, inline and display math, a matplotlib figure, a plotly figure saved with and without
a PNG, widgets with and without a static sibling, and a very long printed output. The PDF is
read back with poppler-utils (pdftotext, pdfimages). Tests that print need a Chromium-based
browser and skip, saying how to get one, when there is none.
"""

from __future__ import annotations

import base64
import io
import re
import shutil
import subprocess
import zipfile

import nbformat
import numpy as np
import pytest
from matplotlib.figure import Figure
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook, new_output

from handin import browser, cover, mathjax, pdf
from handin import html as pdf_html
from handin.code_zip import inspect_notebook
from core.manifest import QUESTIONS
from browser import browser_or_skip, first_line, mathjax_or_skip, pages_of, poppler_or_skip

pytestmark = pytest.mark.slow  # the full tier's: see docs/testing.md

NAME = "Ada Lovelace"
# No hyphens: pdftotext joins a line that wraps after "-" to the next one and drops the hyphen.
LONG_LINE = "LONG_LINE_7f3a = '" + "".join(f"{i:03d}." for i in range(70)) + "END_OF_LONG_LINE_7f3a'"
STREAM_LINES = 600
DEFINED = {"eightpoint", "triangulate"}  # what the sample implements; essentialMatrix stays a stub
HEADINGS = {"Q2": "The eight-point algorithm", "Q3.1": "The essential matrix",
            "Q3.2": "Triangulation", "Q3.3": "Choosing the second camera"}
WIDGET = {"model_id": "0f1e", "version_major": 2, "version_minor": 0}
PLOTLY = {"data": [{"type": "scatter3d", "x": [0, 1], "y": [0, 1], "z": [0, 1]}], "layout": {}}


def figure_png(seed: int, width_in: float = 3.0) -> str:
    rng = np.random.default_rng(seed)
    fig = Figure(figsize=(width_in, 2.0), dpi=60)  # no pyplot: no backend, no global figure list
    fig.subplots().plot(rng.normal(size=12))
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def make_sample(folder) -> dict:
    """Write q2 and q3 notebooks in ``folder``; return what the PDF must show."""
    q2 = new_notebook(cells=[
        new_markdown_cell(f"# Q2 {HEADINGS['Q2']}\nEvery pair satisfies $x_2^T F x_1 = 0$, up to $\\lambda$.\n\n"
                          "$$\\begin{bmatrix} x_2 & y_2 & 1 \\end{bmatrix} F = \\sum_i \\lambda_i e_i$$"),
        new_code_cell(f'STUDENT_NAME = "{NAME}"\n\ndef eightpoint(pts1, pts2, M):\n    return M\n\n{LONG_LINE}',
                      outputs=[new_output("display_data", data={"image/png": figure_png(1), "text/plain": "<Figure>"}),
                               new_output("stream", name="stdout",
                                          text="".join(f"iteration {i:04d}\n" for i in range(STREAM_LINES)))]),
    ])
    q3 = new_notebook(cells=[
        new_markdown_cell("# Q3 Metric reconstruction\nSetup."),
        new_markdown_cell(f"## Q3.1 {HEADINGS['Q3.1']}\nUse $E = K_2^T F K_1$."),
        new_code_cell("def essentialMatrix(F, K1, K2):\n    raise NotImplementedError()", outputs=[
            new_output("display_data", data={"application/vnd.plotly.v1+json": PLOTLY,
                                             "text/html": "<div class='plotly-graph-div'></div>",
                                             "image/png": figure_png(2)}),
            new_output("display_data", data={"application/vnd.plotly.v1+json": PLOTLY,
                                             "text/html": "<div class='plotly-graph-div'></div>"}),
        ]),
        new_markdown_cell(f"## Q3.2 {HEADINGS['Q3.2']}"),
        new_code_cell("def triangulate(C1, pts1, C2, pts2):\n    return pts1", outputs=[
            new_output("display_data", data={"application/vnd.jupyter.widget-view+json": WIDGET,
                                             "text/plain": "interactive(children=(FloatSlider_SIBLING,))"}),
            new_output("display_data", data={"image/png": figure_png(3), "text/plain": "<Figure>"}),
        ]),
        new_markdown_cell(f"## Q3.3 {HEADINGS['Q3.3']}"),
        new_code_cell("slider", outputs=[
            new_output("display_data", data={"application/vnd.jupyter.widget-view+json": WIDGET,
                                             "text/plain": "IntSlider_ALONE(value=3)"})]),
    ])
    nbformat.write(q2, folder / "q2_eightpoint.ipynb")
    nbformat.write(q3, folder / "q3_metric_reconstruction.ipynb")
    present = {"q2_eightpoint", "q3_metric_reconstruction"}
    answered = [q.id for q in QUESTIONS
                if q.notebook in present and q.functions and set(q.functions) <= DEFINED]
    return {"figures": 3, "answered": answered}


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    folder = tmp_path_factory.mktemp("notebooks")
    return folder, make_sample(folder)


@pytest.fixture(scope="module")
def printed(sample, tmp_path_factory):
    """The sample exported once with the default engine; its pages as text."""
    poppler_or_skip()
    browser_or_skip()
    mathjax_or_skip()
    folder, expected = sample
    out = pdf.build_pdf(folder, tmp_path_factory.mktemp("pdf") / "hw4.pdf")
    return out, pages_of(out), expected


# ----------------------------------------------------------------------------- the printed PDF

def test_every_question_starts_a_page(printed):
    _, pages, _ = printed
    for qid, title in HEADINGS.items():
        heading = f"{qid} {title}"
        where = [i for i, p in enumerate(pages) if heading in p]
        assert len(where) == 1, (heading, where)
        assert first_line(pages[where[0]]) == heading


def test_cover_names_the_student_and_the_answered_questions(printed):
    _, pages, expected = printed
    cover = pages[0]
    assert f"Name: {NAME}" in cover
    m = re.search(r"Answered: (.*)", cover)
    assert m and m.group(1).split(" (")[0].split(", ") == expected["answered"]
    assert "not answered" in cover and "notebook missing" in cover


def test_every_figure_is_embedded(printed):
    out, _, expected = printed
    listing = subprocess.run(["pdfimages", "-list", str(out)], check=True, capture_output=True, text=True).stdout
    images = [row for row in listing.splitlines()[2:] if row.split()[2] == "image"]
    assert len(images) >= expected["figures"]


def test_long_code_line_is_whole(printed):
    _, pages, _ = printed
    squeezed = re.sub(r"\s+", "", "".join(pages))
    assert re.sub(r"\s+", "", LONG_LINE) in squeezed


def test_math_is_typeset(printed):
    _, pages, _ = printed
    text = "".join(pages)
    assert "$x_2^T" not in text and "\\begin" not in text and "\\lambda" not in text
    # MathJax writes mathematical italic letters and a big summation sign.
    assert "\N{N-ARY SUMMATION}" in text
    assert "\N{MATHEMATICAL ITALIC SMALL LAMDA}" in text or "\N{GREEK SMALL LETTER LAMDA}" in text


def test_long_output_is_truncated_with_a_note(printed):
    _, pages, _ = printed
    text = "".join(pages)
    assert "iteration 0000" in text and f"iteration {STREAM_LINES - 1:04d}" in text
    assert "iteration 0300" not in text
    assert re.search(r"\d[\d,]* lines omitted from the PDF", text)


def test_interactive_outputs_become_images_or_notes(printed):
    _, pages, _ = printed
    text = "".join(pages)
    assert pdf_html.PLOTLY_NOTE in text
    assert "FloatSlider_SIBLING" not in text and "IntSlider_ALONE" not in text
    assert text.count(pdf_html.PLOTLY_NOTE) == 1  # the plotly output with a PNG printed its PNG
    assert "interactive widget" in text


def test_playwright_engine_waits_for_math(sample, tmp_path):
    pytest.importorskip("playwright", reason="Playwright not installed (pip install playwright)")
    poppler_or_skip()
    browser_or_skip()
    mathjax_or_skip()
    folder, _ = sample
    out = pdf.build_pdf([folder / "q2_eightpoint.ipynb"], tmp_path / "pw.pdf", name="Grace Hopper",
                        engine="playwright")
    pages = pages_of(out)
    assert "Name: Grace Hopper" in pages[0]
    assert first_line(pages[1]) == f"Q2 {HEADINGS['Q2']}"
    assert "\\begin" not in "".join(pages) and "\N{N-ARY SUMMATION}" in "".join(pages)


def test_cli_writes_pdf_and_code_zip(sample, tmp_path):
    from handin.__main__ import main

    browser_or_skip()
    mathjax_or_skip()
    folder, _ = sample
    assert main(["pdf", str(folder), "--out", str(tmp_path / "hw4.pdf"),
                 "--code-zip", str(tmp_path / "hw4_code.zip"), "--name", "Grace Hopper"]) == 0
    assert (tmp_path / "hw4.pdf").read_bytes()[:5] == b"%PDF-"
    assert sorted(zipfile.ZipFile(tmp_path / "hw4_code.zip").namelist()) == \
        ["q2_eightpoint.ipynb", "q3_metric_reconstruction.ipynb"]


# ----------------------------------------------------------------------------- the HTML, no browser

@pytest.fixture(scope="module")
def page_html(sample):
    folder, _ = sample
    mathjax_or_skip()
    return pdf_html.notebooks_to_html(folder)[0]


def test_html_loads_nothing_from_the_network(page_html):
    loaded = re.findall(r"""<(?:script|img|link|iframe)\b[^>]*?\b(?:src|href)=["']([^"']+)""", page_html)
    assert loaded, "expected at least the local MathJax script"
    assert all(not re.match(r"(https?:)?//", url) for url in loaded), loaded
    assert any(url.startswith("file://") and "MathJax.js" in url for url in loaded)


def test_html_breaks_a_page_before_each_question_and_notebook(page_html):
    # Two notebooks plus the three Q3.x headings (Q2 heads its notebook: one break, not two).
    assert page_html.count('class="hw4-page-break"') == 2 + 3


def test_name_argument_beats_student_name(sample):
    folder, _ = sample
    mathjax_or_skip()
    page, _ = pdf_html.notebooks_to_html(folder, name="Grace Hopper")
    assert "Name: Grace Hopper" in page and f"Name: {NAME}" not in page


def test_name_placeholder_when_nobody_is_named(tmp_path):
    mathjax_or_skip()
    nbformat.write(new_notebook(cells=[new_markdown_cell("## Q1.1 Fixating cameras")]), tmp_path / "q1_proofs.ipynb")
    page, _ = pdf_html.notebooks_to_html(tmp_path)
    assert f"Name: {cover.NO_NAME}" in page


def test_folder_without_homework_notebooks_raises(tmp_path):
    nbformat.write(new_notebook(), tmp_path / "Untitled.ipynb")
    with pytest.raises(ValueError, match="notebooks"):
        pdf_html.notebooks_to_html(tmp_path, mathjax=tmp_path)
    with pytest.raises(ValueError, match="out"):
        pdf.build_pdf(tmp_path, tmp_path / "hw4.html")


# ----------------------------------------------------------------------------- preprocessors

def _cell(*outputs):
    return new_code_cell("x", outputs=list(outputs))


def _run(pre, cell):
    return pre.preprocess_cell(cell, {}, 0)[0]


def test_static_outputs_prefer_images_and_drop_widgets():
    png = figure_png(4)
    cell = _run(pdf_html.StaticOutputsPreprocessor(), _cell(
        new_output("display_data", data={"text/html": "<b>x</b>", "image/svg+xml": "<svg/>", "image/png": png}),
        new_output("display_data", data={"application/vnd.jupyter.widget-view+json": WIDGET, "text/plain": "w"}),
        new_output("display_data", data={"application/javascript": "alert(1)"}),
        new_output("execute_result", data={"text/html": "<table></table>", "text/plain": "df"}, execution_count=1)))
    assert [list(o.data) for o in cell.outputs] == [["image/png"], ["text/html"]]
    alone = _run(pdf_html.StaticOutputsPreprocessor(), _cell(
        new_output("display_data", data={"application/vnd.jupyter.widget-view+json": WIDGET, "text/plain": "w"})))
    assert pdf_html.WIDGET_NOTE in alone.outputs[0].data["text/plain"]


def test_truncation_keeps_head_and_tail():
    pre = pdf_html.TruncateOutputsPreprocessor()
    text = "".join(f"row {i}\n" for i in range(1000))
    cell = _run(pre, _cell(new_output("stream", name="stdout", text=text)))
    lines = cell.outputs[0].text.splitlines()
    assert lines[:pre.head] == [f"row {i}" for i in range(pre.head)]
    assert lines[-pre.tail:] == [f"row {i}" for i in range(1000 - pre.tail, 1000)]
    assert f"{1000 - pre.head - pre.tail:,} lines omitted" in lines[pre.head]
    one_line = _run(pre, _cell(new_output("stream", name="stdout", text="x" * 50_000)))
    assert len(one_line.outputs[0].text) < pre.max_chars + 200


def test_huge_images_are_scaled_down():
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (5000, 50), "white").save(buf, format="PNG")
    pre = pdf_html.ScaleImagesPreprocessor()
    cell = _run(pre, _cell(new_output("display_data", data={"image/png": base64.b64encode(buf.getvalue()).decode()})))
    scaled = Image.open(io.BytesIO(base64.b64decode(cell.outputs[0].data["image/png"])))
    assert scaled.width == pre.max_px and scaled.height == round(50 * pre.max_px / 5000)


def test_relative_markdown_images_point_at_the_notebook_folder(tmp_path):
    (tmp_path / "sketch.png").write_bytes(b"png")
    cell = new_markdown_cell('![proof](sketch.png) <img src="sketch.png"> ![web](https://example.org/a.png)')
    cell.metadata["hw4_dir"] = str(tmp_path)
    out = _run(pdf_html.LocalImagesPreprocessor(), cell).source
    uri = (tmp_path / "sketch.png").resolve().as_uri()
    assert out.count(uri) == 2 and "https://example.org/a.png" in out and "hw4_dir" not in cell.metadata


# ----------------------------------------------------------------------------- status, browser lookup

def test_written_question_answered_only_when_placeholder_replaced(tmp_path):
    def status(answer):
        cells = [new_markdown_cell("## Q1.1 Fixating cameras"), new_markdown_cell(answer),
                 new_markdown_cell("## Q1.2 Relative pose"), new_markdown_cell("YOUR ANSWER HERE")]
        cells[1].metadata["nbgrader"] = {"solution": True}
        nbformat.write(new_notebook(cells=cells), tmp_path / "q1_proofs.ipynb")
        return {s.question.id: s.state for s in cover.question_status([inspect_notebook(tmp_path / "q1_proofs.ipynb")])}

    assert status("YOUR ANSWER HERE")["Q1.1"] == "not answered"
    done = status("Since the cameras fixate the same point, $f_{33} = 0$.")
    assert done["Q1.1"] == "answered" and done["Q1.2"] == "not answered"
    assert done["Q2"] == "notebook missing"


def test_find_browser_reports_how_to_install(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.setenv("PLAYWRIGHT_BROWSERS_PATH", str(tmp_path / "none"))
    monkeypatch.delenv("HW4_BROWSER", raising=False)
    monkeypatch.setattr(browser, "MAC_BROWSERS", ())
    with pytest.raises(browser.BrowserNotFoundError, match="apt-get install chromium") as err:
        browser.find_browser()
    assert "playwright install chromium" in str(err.value)
    with pytest.raises(browser.BrowserNotFoundError, match="browser"):
        browser.find_browser(str(tmp_path / "no-such-chrome"))
    monkeypatch.setattr(browser, "in_colab", lambda: False)
    with pytest.raises(browser.BrowserNotFoundError):
        browser.ensure_browser()  # outside Colab nothing is installed behind the student's back


def test_find_browser_finds_a_playwright_install(tmp_path, monkeypatch):
    chrome = tmp_path / "chromium-1200" / "chrome-linux64" / "chrome"
    chrome.parent.mkdir(parents=True)
    chrome.write_text("#!/bin/sh\n")
    chrome.chmod(0o755)
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    monkeypatch.setenv("PLAYWRIGHT_BROWSERS_PATH", str(tmp_path))
    monkeypatch.delenv("HW4_BROWSER", raising=False)
    assert browser.find_browser() == str(chrome)


def test_find_mathjax_honours_the_environment(tmp_path, monkeypatch):
    (tmp_path / "config").mkdir()
    (tmp_path / "fonts" / "HTML-CSS" / "STIX-Web" / "woff").mkdir(parents=True)
    (tmp_path / "MathJax.js").write_text("")
    (tmp_path / "config" / "TeX-AMS-MML_HTMLorMML-full.js").write_text("")
    monkeypatch.setenv("HW4_MATHJAX", str(tmp_path / "MathJax.js"))
    assert mathjax.find_mathjax() == tmp_path


# ------------------------------------------------------------- setup cell, wrapping, blank answers

SETUP_SOURCE = pdf_html.SETUP_FIRST_LINE + "  It finds the kit.\n" + "".join(
    f"setup_statement_{i:02d} = {i}  # kit plumbing\n" for i in range(40))
REPORT_LINE = ("  ok   the epipolar lines pass within 0.04 px of the matches on the generated scene, "
               "and the uint16 points give the same F as float points do, as they must")


def test_setup_cell_is_one_line_and_keeps_its_output():
    cell = new_code_cell(SETUP_SOURCE, outputs=[new_output("stream", name="stdout", text="homework kit: /x\n")])
    other = new_code_cell("x = 1  # Setup: not the first line, so it is the student's")
    pre = pdf_html.SetupCellPreprocessor()
    out, _ = pre.preprocess_cell(cell, {}, 0)
    assert len(out.source.splitlines()) == 1 and "41 lines" in out.source
    assert out.outputs[0].text == "homework kit: /x\n"
    assert pre.preprocess_cell(other, {}, 1)[0].source == other.source


def test_colab_notes_are_left_out_and_their_page_break_moves_on():
    tagged = new_markdown_cell("How to work on Colab: ...", metadata={"tags": [pdf_html.PLUMBING_TAG,
                                                                              pdf_html.PAGE_START_TAG]})
    legacy = new_markdown_cell("*Colab: this kit comes from file:///srv/kit, which Colab cannot open; ...*")
    linked = new_markdown_cell("[Open this notebook in Colab](https://colab.research.google.com/x), then ...")
    kept = [new_markdown_cell("# Homework 4, problem 2"), new_markdown_cell("The data: two views.")]
    nb = new_notebook(cells=[kept[0], tagged, legacy, linked, kept[1]])
    out, _ = pdf_html.PlumbingNotesPreprocessor().preprocess(nb, {})
    assert [c.source for c in out.cells] == [c.source for c in kept]
    assert pdf_html.PAGE_START_TAG in out.cells[1].metadata["tags"]


def test_cli_says_once_that_the_hand_in_notebook_is_left_out(sample, tmp_path, capsys):
    from handin.__main__ import main
    from handin.hand_in_notebook import HAND_IN_NAME, hand_in_notebook

    browser_or_skip()
    mathjax_or_skip()
    folder = tmp_path / "mine"
    shutil.copytree(sample[0], folder)
    nbformat.write(hand_in_notebook("print('setup')"), folder / HAND_IN_NAME)
    assert main(["pdf", str(folder), "--out", str(tmp_path / "hw4.pdf"),
                 "--code-zip", str(tmp_path / "hw4_code.zip")]) in (0, 1)  # 1: functions missing
    said = capsys.readouterr()
    assert (said.out + said.err).count(f"left out {HAND_IN_NAME}") == 1, said


def test_css_wraps_at_spaces_not_inside_words():
    css = (pdf_html.ASSETS / "hw4.css").read_text()
    assert "overflow-wrap: anywhere" not in css and "word-break: break-all" not in css
    assert "overflow-wrap: break-word" in css


def _written(tmp_path, q1_answers, q6_answer):
    cells = [new_markdown_cell("## Q1.1 Fixating cameras"), new_markdown_cell(q1_answers[0]),
             new_markdown_cell("## Q1.2 Relative pose"), new_markdown_cell(q1_answers[1])]
    nbformat.write(new_notebook(cells=cells), tmp_path / "q1_proofs.ipynb")
    q6 = new_notebook(cells=[
        new_markdown_cell("## Q6 Three-view keypoints"),
        new_code_cell("def MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres):\n    return C1, 0.0\n\n"
                      "def plot_3d_keypoint_video(pts_3d_video):\n    return None"),
        new_markdown_cell(q6_answer)])
    nbformat.write(q6, tmp_path / "q6_multiview_car.ipynb")
    infos = [inspect_notebook(tmp_path / f) for f in ("q1_proofs.ipynb", "q6_multiview_car.ipynb")]
    return infos, {s.question.id: s for s in cover.question_status(infos)}


def test_blank_written_answers_are_flagged_placeholder_or_empty(tmp_path):
    infos, st = _written(tmp_path, ["YOUR ANSWER HERE", "   \n"], "YOUR ANSWER HERE")
    assert cover.blank_answers(infos) == ["Q1.1", "Q1.2", "Q6"]
    assert st["Q1.1"].state == st["Q1.2"].state == "not answered"
    assert st["Q6"].state == "partial" and "blank" in st["Q6"].detail  # the code is there, the text is not
    page = cover.cover_html("A", list(st.values()), [], "today")
    assert re.search(r"Blank written answers: Q1\.1, Q1\.2, Q6", page)

    infos, st = _written(tmp_path, ["$f_{33} = 0$ because ...", "R_rel = R2 R1^T"], "Two or three views, then DLT.")
    assert cover.blank_answers(infos) == []
    assert st["Q1.1"].state == st["Q1.2"].state == st["Q6"].state == "answered"
    assert "Blank written answers" not in cover.cover_html("A", list(st.values()), [], "today")


@pytest.fixture(scope="module")
def printed_setup_and_report(tmp_path_factory):
    """A q1 notebook with a long setup cell, a check report longer than a line and a blank answer."""
    poppler_or_skip()
    browser_or_skip()
    mathjax_or_skip()
    folder = tmp_path_factory.mktemp("setup")
    nb = new_notebook(cells=[
        new_code_cell(SETUP_SOURCE, outputs=[new_output("stream", name="stdout", text="homework kit: /kit\n")]),
        new_markdown_cell("## Q1.1 Fixating cameras"), new_markdown_cell("YOUR ANSWER HERE"),
        new_code_cell("report = check()", outputs=[new_output("stream", name="stdout",
                                                              text=(REPORT_LINE + "\n") * 3)]),
        new_markdown_cell("## Q1.2 Relative pose"), new_markdown_cell("$R_{rel} = R_2 R_1^T$"),
    ])
    nbformat.write(nb, folder / "q1_proofs.ipynb")
    out = pdf.build_pdf(folder, tmp_path_factory.mktemp("pdf") / "hw4.pdf")
    return pages_of(out)


def test_printed_setup_cell_takes_one_line(printed_setup_and_report):
    text = "\n".join(printed_setup_and_report)
    assert "setup_statement_" not in text
    assert sum("Setup cell of the homework kit" in line for line in text.splitlines()) == 1


def words_split_across_lines(text: str, expected: str) -> list[str]:
    """Pairs of consecutive lines of ``text`` whose join cuts one word of ``expected`` in two."""
    words = set(re.findall(r"[A-Za-z0-9.]+", expected))
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    bad = []
    for a, b in zip(lines, lines[1:]):
        left, right = re.findall(r"[A-Za-z0-9.]+$", a), re.findall(r"^[A-Za-z0-9.]+", b)
        if left and right and left[0] + right[0] in words and left[0] not in words:
            bad.append(f"{a!r} / {b!r}")
    return bad


def test_printed_report_lines_wrap_at_spaces(printed_setup_and_report):
    text = "\n".join(printed_setup_and_report)
    assert "generated scene" in text.replace("\n", " ")
    assert words_split_across_lines(text, REPORT_LINE) == []


def test_printed_cover_flags_the_blank_answer(printed_setup_and_report):
    assert re.search(r"Blank written answers: Q1\.1\b", printed_setup_and_report[0])
