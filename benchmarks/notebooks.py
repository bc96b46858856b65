"""Run each answer-key notebook top to bottom headless and print how long it took (goal: < 60 s each).

    python benchmarks/notebooks.py [--data DIR]

The baseline printed beside each notebook is a kernel that starts, imports the kit and stops, in
the same run: the ratio says how much of the time is the homework itself.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import nbformat
from nbclient import NotebookClient

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from anywhere without installing
from core.paths import DATA_DIR, KIT_ROOT  # noqa: E402


def run(nb, folder: Path) -> float:
    t0 = time.perf_counter()
    NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(folder)}}).execute()
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=str(DATA_DIR))
    args = ap.parse_args(argv)
    os.environ["HW4_DATA"] = args.data
    key = KIT_ROOT / "notebooks" / "key"
    baseline_nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("import starter, numpy, scipy, matplotlib")])
    base = run(baseline_nb, key)
    print(f"{'notebook':<32}{'seconds':>10}{'x kernel start':>16}")
    print(f"{'(kernel start + imports)':<32}{base:>10.1f}{1.0:>16.1f}")
    worst = 0.0
    for path in sorted(key.glob("q*.ipynb")):
        secs = run(nbformat.read(path, as_version=4), key)
        worst = max(worst, secs)
        print(f"{path.name:<32}{secs:>10.1f}{secs / base:>16.1f}")
    print(f"slowest: {worst:.1f} s (goal: under 60 s each)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
