"""The PDF of the real answer key, executed headless and printed offline with Debian's chromium."""

from __future__ import annotations

import re
import subprocess

import nbformat
import pytest

from handin import pdf
from core.manifest import NOTEBOOKS, QUESTIONS
from core.paths import NOTEBOOKS_DIR

from browser import browser_or_skip, mathjax_or_skip, poppler_or_skip, first_line, pages_of

KEY = NOTEBOOKS_DIR / "key"

pytestmark = [pytest.mark.slow, pytest.mark.browser]


@pytest.fixture(scope="module")
def printed_key(tmp_path_factory):
    poppler_or_skip()
    browser_or_skip()
    mathjax_or_skip()
    from nbclient import NotebookClient

    folder = tmp_path_factory.mktemp("key")
    figures = 0
    for stem in NOTEBOOKS:
        nb = nbformat.read(KEY / f"{stem}.ipynb", as_version=4)
        NotebookClient(nb, timeout=120, kernel_name="python3", resources={"metadata": {"path": str(KEY)}},
                       ).execute()
        figures += sum(1 for c in nb.cells if c.cell_type == "code"
                       for o in c.get("outputs", []) if "image/png" in o.get("data", {}))
        nbformat.write(nb, folder / f"{stem}.ipynb")
    out = pdf.build_pdf(folder, tmp_path_factory.mktemp("pdf") / "key.pdf", name="Answer Key")
    return out, pages_of(out), figures


def test_every_question_title_starts_a_page(printed_key):
    _, pages, _ = printed_key
    for q in QUESTIONS:
        starts = [i for i, p in enumerate(pages) if re.match(rf"{re.escape(q.id)}\b", first_line(p))]
        assert len(starts) == 1, (q.id, [first_line(p) for p in pages])


def test_every_figure_of_the_key_is_in_the_pdf(printed_key):
    out, _, figures = printed_key
    listing = subprocess.run(["pdfimages", "-list", str(out)], check=True, capture_output=True, text=True).stdout
    images = [row for row in listing.splitlines()[2:] if row.split()[2] == "image"]
    assert figures >= 8 and len(images) >= figures


def test_math_is_rendered_and_the_cover_lists_every_question(printed_key):
    _, pages, _ = printed_key
    text = "\f".join(pages)
    assert "\\mathbf" not in text and "$\\" not in text
    assert "Name: Answer Key" in pages[0]
    answered = re.search(r"Answered: (.*)", pages[0]).group(1)
    for q in QUESTIONS:
        if q.functions:
            assert q.id in answered


def test_the_hand_in_notebook_makes_the_pdf_and_the_zip(tmp_path):
    poppler_or_skip()
    browser_or_skip()
    mathjax_or_skip()
    import shutil

    from nbclient import NotebookClient

    notebooks = KEY.parent
    for stem in NOTEBOOKS:
        shutil.copy(notebooks / f"{stem}.ipynb", tmp_path)
    nb = nbformat.read(notebooks / "hand_in.ipynb", as_version=4)
    NotebookClient(nb, timeout=180, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}).execute()
    assert (tmp_path / "hw4.pdf").stat().st_size > 10_000
    import zipfile

    with zipfile.ZipFile(tmp_path / "hw4_code.zip") as z:
        assert sorted(n.split("/")[-1] for n in z.namelist()) == sorted(f"{s}.ipynb" for s in NOTEBOOKS)
    # The untouched notebooks are reported as such on the cover, not as answered.
    assert "Answered: none" in pages_of(tmp_path / "hw4.pdf")[0] or "(0 of" in pages_of(tmp_path / "hw4.pdf")[0]


def test_no_setup_cell_pages_one_line_per_notebook(printed_key):
    _, pages, _ = printed_key
    text = "\n".join(pages)
    # Lines of the setup cell's code never reach the PDF; its one-line stand-in does, once a notebook.
    for code in ("importlib.metadata", "subprocess.run(", "sys.path.insert", "KIT_REPO ="):
        assert code not in text, code
    assert sum("Setup cell of the homework kit" in line for line in text.splitlines()) == len(NOTEBOOKS)


def _squeezed(text: str) -> str:
    # pdftotext wraps long lines: compare without any whitespace.
    return re.sub(r"\s+", "", text)


def test_no_plumbing_on_any_page(printed_key):
    """The kit's plumbing is not the student's work: the refineF comparison's code (now in
    starter.refine_comparison, called in one line), the Colab link and how-to are on no page."""
    import inspect

    from starter import refine_comparison

    _, pages, _ = printed_key
    text = _squeezed("\n".join(pages))
    body = inspect.getsource(refine_comparison.reprojection_errors).split('"""')[2]
    code = [line.strip() for line in body.splitlines() if len(line.strip()) >= 20]
    assert len(code) > 15
    # The lines of the 30-line cell the notebook held before, and the comparison's lines now.
    code += ["def without_refineF(eightpoint):", 'names["refineF"] = lambda F, pts1, pts2:',
             "per_point = per_point + np.sum("]
    assert [line for line in code if _squeezed(line) in text] == []
    for note in ("Open this notebook in Colab", "Colab: this kit comes from", "Working on Colab",
                 "Placeholder link", "Save a copy in Drive"):
        assert _squeezed(note) not in text, note
    assert "reprojection_errors(eightpoint, findM2, triangulate, d)" in "\n".join(pages)


def test_q3_2_errors_are_printed_on_their_own_page(printed_key):
    """Q3.2's reprojection errors need findM2 (Q3.3), so they come after it, on a page of their own."""
    _, pages, _ = printed_key
    firsts = [first_line(p) for p in pages]
    q33 = next(i for i, f in enumerate(firsts) if f.startswith("Q3.3"))
    errors = next(i for i, f in enumerate(firsts) if f.startswith("Reprojection errors (Q3.2"))
    assert errors > q33
    assert not [i for i in range(q33, errors) if "total reprojection error" in pages[i]], firsts[q33:errors + 1]
    assert "total reprojection error" in pages[errors]


def test_check_reports_wrap_at_spaces(printed_key):
    """No line of a check report ends inside a word: the words printed whole inside lines of the
    PDF are the vocabulary, and a line end joined to the next line's start must not form one of
    them out of two pieces that are not words themselves."""
    _, pages, _ = printed_key
    lines = [line.strip() for page in pages for line in page.splitlines() if line.strip()]
    token = r"[A-Za-z][A-Za-z0-9_]*"
    vocabulary = {t for line in lines for t in re.findall(token, line)[1:-1]}
    reports, inside = [], False
    for line in lines:
        if re.match(r"check \w+: \d+/\d+ passed", line):
            inside = True
        elif inside and not re.match(r"[✓✗!•(a-z0-9]", line):
            inside = False
        if inside:
            reports.append(line)
    assert len(reports) > 20, "the check reports of the answer key were not found in its PDF"
    cut = []
    for a, b in zip(reports, reports[1:]):
        left, right = re.findall(token + "$", a), re.findall("^" + token, b)
        if left and right and left[0] + right[0] in vocabulary \
                and not (left[0] in vocabulary and right[0] in vocabulary):
            cut.append(f"{a!r} / {b!r}")
    assert cut == []


def test_the_answer_keys_cover_flags_no_blank_answer(printed_key):
    _, pages, _ = printed_key
    assert "Blank written answers" not in pages[0]
