"""The PDF of the real answer key, executed headless and printed offline with Debian's chromium."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import nbformat
import pytest

from handin import pdf
from core.manifest import NOTEBOOKS, QUESTIONS

from test_pdf import _browser_or_skip, _mathjax_or_skip, _poppler_or_skip, first_line, pages_of

KEY = Path(__file__).resolve().parents[1] / "notebooks" / "key"

pytestmark = [pytest.mark.slow, pytest.mark.browser]


@pytest.fixture(scope="module")
def printed_key(tmp_path_factory):
    _poppler_or_skip()
    _browser_or_skip()
    _mathjax_or_skip()
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
    _poppler_or_skip()
    _browser_or_skip()
    _mathjax_or_skip()
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
