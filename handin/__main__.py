"""``python -m handin``: what a student runs to hand in the homework.

  pdf   your notebooks -> one Gradescope-ready PDF (and, with --code-zip, the code zip)
  zip   your notebooks -> the code zip for the autograder, with what is missing
"""

from __future__ import annotations

import sys

from core.commands import Command, run

COMMANDS = {
    "pdf": Command("handin.pdf", "main", "export the notebooks to a Gradescope-ready PDF (and the code zip)",
                   needs=("nbconvert",), install="pip install nbconvert jupyter-server-mathjax"),
    "zip": Command("handin.code_zip", "main", "write the code zip for the autograder and list what is missing",
                   needs=("nbformat",), install="pip install nbformat"),
}


def main(argv=None) -> int:
    return run("python -m handin", __doc__, COMMANDS, argv)


if __name__ == "__main__":
    sys.exit(main())
