"""Time the Gradescope PDF export of a folder of notebooks. Goal: all six notebooks in under 60 s.

Usage::

    python benchmarks/pdf_export.py                 # six synthetic notebooks shaped like the kit's
    python benchmarks/pdf_export.py notebooks/      # a real folder of executed notebooks
    python benchmarks/pdf_export.py --repeat 3 --engine playwright

The synthetic notebooks follow the manifest (one notebook per stem, one heading per question)
and carry what costs time when printing: matplotlib figures, inline and display math, plotly and
widget outputs with their static PNGs, and printed logs. Prints the time of the HTML step and of
the printing step, the page count and the PDF size.
"""

from __future__ import annotations

import argparse
import base64
import io
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path

import nbformat
import numpy as np
from matplotlib.figure import Figure
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook, new_output

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from anywhere without installing
from handin import html as pdf_html  # noqa: E402
from handin import pdf  # noqa: E402
from core.manifest import NOTEBOOKS, QUESTIONS  # noqa: E402

GOAL_S = 60.0
FORMULAS = [
    r"$x_2^T F x_1 = 0$", r"$E = K_2^T F K_1$", r"$\lambda \tilde{x} = K [R \mid t] \tilde{X}$",
    r"$$A f = 0, \quad A \in \mathbb{R}^{N \times 9}$$",
    r"$$\min_{X} \sum_i \| x_i - \pi(C_i X) \|^2$$",
    r"$$F = \begin{bmatrix} f_{11} & f_{12} & f_{13} \\ f_{21} & f_{22} & f_{23} \\ f_{31} & f_{32} & f_{33} \end{bmatrix}$$",
]


def _figure(rng: np.random.Generator) -> str:
    fig = Figure(figsize=(6.4, 4.0), dpi=100)
    ax = fig.subplots()
    ax.scatter(rng.uniform(0, 640, 200), rng.uniform(0, 480, 200), s=4)
    ax.set_xlim(0, 640)
    ax.set_ylim(480, 0)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def make_notebooks(folder: Path, rng: np.random.Generator) -> None:
    """Six notebooks shaped like the kit's, with outputs, written to ``folder``."""
    for stem in NOTEBOOKS:
        cells = [new_markdown_cell(f"# {stem}\nSet-up and imports."),
                 new_code_cell('STUDENT_NAME = "Benchmark Student"\nimport numpy as np')]
        for q in (q for q in QUESTIONS if q.notebook == stem):
            text = " ".join(FORMULAS[i % len(FORMULAS)] for i in range(8))
            cells.append(new_markdown_cell(f"## {q.id} {q.title}\n{text}"))
            for f in q.functions or ("helper",):
                cells.append(new_code_cell(f"def {f}(*args):\n    return args\n", outputs=[
                    new_output("display_data", data={"image/png": _figure(rng), "text/plain": "<Figure>"}),
                    new_output("stream", name="stdout", text="".join(f"step {i}: {rng.normal():.4f}\n"
                                                                     for i in range(150)))]))
            cells.append(new_code_cell("show()", outputs=[
                new_output("display_data", data={"application/vnd.plotly.v1+json": {"data": []},
                                                 "text/html": "<div class='plotly-graph-div'></div>",
                                                 "image/png": _figure(rng)}),
                new_output("display_data", data={"application/vnd.jupyter.widget-view+json":
                                                 {"model_id": "m", "version_major": 2, "version_minor": 0},
                                                 "text/plain": "interactive(...)"})]))
            cells.append(new_markdown_cell("YOUR ANSWER HERE" if q.by_hand else f"The answer to {q.id}."))
        nbformat.write(new_notebook(cells=cells), folder / f"{stem}.ipynb")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", nargs="?", type=Path, help="notebooks to export (default: synthetic)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--engine", choices=("cli", "playwright"), default="cli")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="hw4-bench-") as tmp:
        tmp = Path(tmp)
        folder = args.folder
        if folder is None:
            folder = tmp / "notebooks"
            folder.mkdir()
            make_notebooks(folder, np.random.default_rng(args.seed))
        totals, html_times = [], []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            page, _ = pdf_html.notebooks_to_html(folder)
            t1 = time.perf_counter()
            html_path = tmp / "hw4.html"
            html_path.write_text(page, encoding="utf-8")
            out = pdf.html_to_pdf(html_path, tmp / "hw4.pdf", engine=args.engine)
            t2 = time.perf_counter()
            html_times.append(t1 - t0)
            totals.append(t2 - t0)
        pages = len(re.findall(rb"/Type\s*/Page(?!s)", out.read_bytes()))
        total = statistics.median(totals)
        print(f"notebooks: {len(list(folder.glob('*.ipynb')))} from {folder}")
        print(f"html {statistics.median(html_times):.1f} s, print {total - statistics.median(html_times):.1f} s, "
              f"total {total:.1f} s (median of {args.repeat}, engine {args.engine}); goal < {GOAL_S:.0f} s: "
              f"{'met' if total < GOAL_S else 'MISSED'}")
        print(f"pdf: {out.stat().st_size / 2**20:.2f} MB, {pages} pages")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
