"""Grading a submission again with a keep (``HW4_KEEP_INPUTS``) beside grading it without one.

    python benchmarks/regrade_keep.py [--runs 5]

One corpus submission (not the answer key) is graded with ``python -m autograder grade`` at the
kit's quick settings, ``--no-pictures``, each time into a new output folder: the baseline without
a keep, then the same with a keep that an earlier run filled (its hidden inputs and this
submission's draw are read back, not made), in turn.  Printed: median wall and CPU seconds (the
grader and everything it started) of each, and their ratio.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from anywhere without installing
from core.paths import KIT_ROOT  # noqa: E402
sys.path.insert(0, str(KIT_ROOT / "tests" / "support"))

SUBMISSION = "transposed_F_loses_Q2"


def _grade(sub: Path, config: Path, out: Path, keep: Path | None) -> tuple[float, float]:
    env = {k: v for k, v in os.environ.items() if k != "HW4_KEEP_INPUTS"}
    env["PYTHONPATH"] = str(KIT_ROOT)
    if keep is not None:
        env["HW4_KEEP_INPUTS"] = str(keep)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "autograder", "grade", str(sub), "--out", str(out), "--config", str(config),
                    "--quiet", "--no-pictures"], cwd=KIT_ROOT, env=env, check=True, capture_output=True)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=5, help="runs of each, in turn (default 5)")
    args = ap.parse_args(argv)

    import corpus

    from autograder.inputs.config import quick_config

    root = Path(tempfile.mkdtemp(prefix="keep-bench-"))
    sub = corpus.build(SUBMISSION, root / "subs")
    config = root / "grader.json"
    config.write_text(json.dumps(quick_config().to_dict()))
    keep = root / "keep"
    _grade(sub, config, root / "warm-up", keep)  # fills the keep (and warms the disk cache)
    times = {"without a keep": [], "with a filled keep": []}
    for k in range(args.runs):
        times["without a keep"].append(_grade(sub, config, root / f"plain-{k}", None))
        times["with a filled keep"].append(_grade(sub, config, root / f"kept-{k}", keep))
    medians = {}
    for name, runs in times.items():
        medians[name] = (statistics.median(w for w, _ in runs), statistics.median(c for _, c in runs))
        print(f"{name:>20}: wall {medians[name][0]:.2f} s, CPU {medians[name][1]:.2f} s (median of {args.runs})")
    (w0, c0), (w1, c1) = medians.values()
    print(f"{'ratio':>20}: wall {w1 / w0:.2f}, CPU {c1 / c0:.2f} (with / without)")
    print(f"keep: {sum(p.stat().st_size for p in keep.iterdir()) / 1e6:.1f} MB in {len(list(keep.iterdir()))} files")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
