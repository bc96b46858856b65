"""The hand-in notebook: one PDF and one code zip from a student's notebooks, in Colab or locally.

Its first code cell is the homework notebooks' own setup cell (``kit.notebooks`` passes it in):
on Colab it mounts Google Drive and makes the kit there importable, and the student's notebooks
are found where the homework notebooks find each other (``starter.notebook_import``: the course
folder MyDrive/hw4 and MyDrive/Colab Notebooks, whatever Colab named them), so nothing is
uploaded.  Locally it takes the notebooks beside it.  The PDF and the zip are written to the
course folder (Drive on Colab) and, on Colab, downloaded too.  ``python -m kit notebooks``
writes it as notebooks/hand_in.ipynb.
"""

from __future__ import annotations

import nbformat

__all__ = ["hand_in_notebook", "HAND_IN_NAME"]

HAND_IN_NAME = "hand_in.ipynb"

_INTRO = """\
# Hand in: one PDF for Gradescope and the zip of your notebooks

Run the cells in order. The PDF has a cover with your name and the questions you answered, and
each question starts on a new page, so that matching pages to questions on Gradescope is one
click per question. Every figure is printed as an image, long code lines wrap, and math is
rendered without internet. The zip holds your notebooks, which the autograder runs.

- **Colab:** save your notebooks first (Colab keeps them in Google Drive: MyDrive/hw4 or
  MyDrive/Colab Notebooks, "Copy of ..." names are fine). The first cell mounts Drive as in
  your notebooks; the list below shows which file is used for each problem (the most recently
  saved). `hw4.pdf` and `hw4_code.zip` are written to MyDrive/hw4 and downloaded.
- **Your own machine:** keep this notebook in the folder of your notebooks; the files are
  written beside them."""

_FIND = """\
from starter.notebook_import import NOTEBOOKS_ENV, homework_notebooks

STUDENT_NAME = ""  # your name for the cover; left empty, the STUDENT_NAME of your notebooks is used
IN_COLAB = "google.colab" in sys.modules
notebooks = homework_notebooks()
for stem, path in notebooks.items():
    print(f"{stem}: {path}")
out_dir = Path(os.environ[NOTEBOOKS_ENV].split(os.pathsep)[0]) if NOTEBOOKS_ENV in os.environ else Path.cwd()
print("the PDF and the zip go to:", out_dir)"""

_BUILD = """\
from handin.browser import ensure_browser
from handin.code_zip import build_code_zip
from handin.pdf import build_pdf

ensure_browser()  # finds Chromium; in Colab it installs one the first time (a minute or two)
pdf = build_pdf(list(notebooks.values()), out_dir / "hw4.pdf", name=STUDENT_NAME or None)
report = build_code_zip(list(notebooks.values()), out_dir / "hw4_code.zip")
print("PDF:", pdf)
print(report)
if IN_COLAB:
    from google.colab import files

    files.download(str(pdf))
    files.download(str(out_dir / "hw4_code.zip"))"""


def hand_in_notebook(setup_code: str) -> nbformat.NotebookNode:
    """The hand-in notebook whose first code cell is ``setup_code``, the homework notebooks' setup cell."""
    cells = [
        nbformat.v4.new_markdown_cell(_INTRO),
        nbformat.v4.new_code_cell(setup_code),
        nbformat.v4.new_code_cell(_FIND),
        nbformat.v4.new_code_cell(_BUILD),
    ]
    nb = nbformat.v4.new_notebook(cells=cells)
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    return nb
