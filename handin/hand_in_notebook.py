"""The hand-in notebook: one PDF and one code zip from a student's notebooks, in Colab or locally.

Each Colab notebook runs on its own machine, so no single notebook can see the others there; the
hand-in notebook asks for the saved .ipynb files (File > Download in each), then does what
``python -m handin pdf`` does.  Locally it takes the notebooks beside it.  ``python -m kit
notebooks`` writes it as notebooks/hand_in.ipynb.
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

- **Colab:** in each of your notebooks, save and then *File > Download > Download .ipynb*;
  upload those files when the second cell asks. Two files come back to download: `hw4.pdf`
  and `hw4_code.zip`.
- **Your own machine:** keep this notebook in the folder of your notebooks; the files are
  written beside them."""

_COLAB_SETUP = """\
# Colab only: fetch the kit (for its PDF tools) the first time.  Locally this cell does nothing.
import subprocess
import sys
from pathlib import Path

KIT_REPO = "{repo}"
IN_COLAB = "google.colab" in sys.modules
if IN_COLAB and not Path("hw4-kit").is_dir():
    subprocess.run(["git", "clone", "--quiet", "--depth", "1", KIT_REPO, "hw4-kit"], check=True)
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "nbconvert", "jupyter-server-mathjax"],
                   check=True)"""

_SETUP = """\
STUDENT_NAME = ""  # your name for the cover; left empty, the STUDENT_NAME of your notebooks is used
kit = Path("hw4-kit").resolve() if IN_COLAB else next(
    (p for p in [Path.cwd(), *Path.cwd().parents] if (p / "handin" / "pdf.py").is_file()), None)
if kit is not None and str(kit) not in sys.path:
    sys.path.insert(0, str(kit))
folder = Path.cwd()
print("notebooks folder:", folder)"""

_UPLOAD = """\
if IN_COLAB:
    from google.colab import files
    folder = Path("/content/hand_in")
    folder.mkdir(exist_ok=True)
    for name, data in files.upload().items():  # choose your q1 ... q6 .ipynb files
        (folder / Path(name).name).write_bytes(data)
print(sorted(p.name for p in folder.glob("*.ipynb")))"""

_BUILD = """\
from handin.browser import ensure_browser
from handin.code_zip import build_code_zip
from handin.pdf import build_pdf

ensure_browser()  # finds Chromium; in Colab it installs one the first time (a minute or two)
pdf = build_pdf(folder, folder / "hw4.pdf", name=STUDENT_NAME or None)
report = build_code_zip(folder, folder / "hw4_code.zip")
print("PDF:", pdf)
print(report)
if IN_COLAB:
    files.download(str(pdf))
    files.download(str(folder / "hw4_code.zip"))"""


def hand_in_notebook(repo_url: str) -> nbformat.NotebookNode:
    """The hand-in notebook for the kit published at ``repo_url``."""
    cells = [
        nbformat.v4.new_markdown_cell(_INTRO),
        nbformat.v4.new_code_cell(_COLAB_SETUP.format(repo=repo_url)),
        nbformat.v4.new_code_cell(_SETUP),
        nbformat.v4.new_code_cell(_UPLOAD),
        nbformat.v4.new_code_cell(_BUILD),
    ]
    nb = nbformat.v4.new_notebook(cells=cells)
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    return nb
