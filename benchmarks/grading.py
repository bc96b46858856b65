"""Grading throughput: 20 submissions graded with --jobs 1 and with --jobs 2, in submissions per minute.

    python benchmarks/grading.py [--count 20] [--quick] [--keep DIR]
    python benchmarks/grading.py --class-of 30 [--quick]   # a class with 2 infinite loops and 2 memory bombs

The submissions are the answer key and the corpus of tests/corpus (mistakes, valid alternatives,
broken notebooks; the hostile ones are left out, they measure the sandbox rather than a class),
repeated until there are --count.  Settings: the grader's defaults (``GradingConfig()``, the dev
secret) or, with --quick, the small ones of the kit's tests.  The hidden inputs are made once,
before the clock starts, as a real batch does; their cost is printed on its own, and so is the
time of grading the answer key alone.  The batches run without their canary (the answer key graded
first, once per batch), whose cost is printed on its own too: the figures are those of grading.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from anywhere without installing
from core.paths import KIT_ROOT  # noqa: E402
sys.path.insert(0, str(KIT_ROOT / "tests"))

_HOSTILE = ("bomb", "loop", "exit", "process_left", "patched", "always_true", "reads_grader", "writes_results",
            "prints_fake")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--count", type=int, default=20, help="submissions per run (default 20)")
    ap.add_argument("--quick", action="store_true", help="the small settings of the kit's tests")
    ap.add_argument("--keep", default=None, help="write the submissions and results here instead of a temp folder")
    ap.add_argument("--class-of", type=int, default=0, metavar="N",
                    help="instead: one class of N submissions, two of them with an infinite loop and two with a "
                         "memory bomb, graded as a TA would (--jobs 2, canary on), beside the answer key alone")
    args = ap.parse_args(argv)

    import corpus

    from autograder.config import GradingConfig, quick_config
    from autograder.batch import grade_batch
    from autograder.hidden.inputs import build_hidden_inputs

    config = quick_config() if args.quick else GradingConfig()
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="hw4-grading-bench-"))
    names = ["key_full_marks"] + [n for n in corpus.CASES
                                  if n != "key_full_marks" and not any(h in n for h in _HOSTILE)]
    paths = []
    for k in range(args.count):
        name = names[k % len(names)]
        folder = corpus.build(name, root / "subs" / f"{k:02d}")
        paths.append(folder)

    if args.class_of:
        hostile = ["infinite_loop_in_rodriguesResidual_loses_part_of_Q5"] * 2 + ["memory_bomb_in_eightpoint_loses_Q2"] * 2
        class_names = hostile + [names[k % len(names)] for k in range(max(args.class_of - len(hostile), 0))]
        paths = [corpus.build(n, root / "class" / f"{k:02d}") for k, n in enumerate(class_names)]

    t0 = time.perf_counter()
    build_hidden_inputs(config)
    print(f"hidden inputs: {time.perf_counter() - t0:.1f} s (once per batch)")

    if args.class_of:
        t0 = time.perf_counter()
        key = grade_batch([corpus.build("key_full_marks", root / "key-sub")], root / "key", jobs=1, config=config,
                          resume=False, progress=False)[0]
        print(f"answer key alone (with its canary): {time.perf_counter() - t0:.1f} s, {key.score:g} points")
        t0 = time.perf_counter()
        records = grade_batch(paths, root / "class-out", jobs=2, config=config, resume=False, progress=False)
        seconds = time.perf_counter() - t0
        print(f"class of {len(records)} (2 infinite loops, 2 memory bombs) at --jobs 2: {seconds:.1f} s, "
              f"{60 * len(records) / seconds:.1f} submissions per minute (target: under 90 s)")
        if not args.keep:
            shutil.rmtree(root, ignore_errors=True)
        return 0

    key_out = root / "key"
    t0 = time.perf_counter()
    key = grade_batch(paths[:1], key_out, jobs=1, config=config, resume=False, progress=False, canary=False)[0]
    print(f"answer key alone: {time.perf_counter() - t0:.1f} s, {key.score:g} points")
    t0 = time.perf_counter()
    grade_batch(paths[:1], root / "key-canary", jobs=1, config=config, resume=False, progress=False)
    print(f"answer key with the batch's canary: {time.perf_counter() - t0:.1f} s")

    for jobs in (1, 2):
        out = root / f"out-jobs{jobs}"
        shutil.rmtree(out, ignore_errors=True)
        t0 = time.perf_counter()
        records = grade_batch(paths, out, jobs=jobs, config=config, resume=False, progress=False, canary=False)
        seconds = time.perf_counter() - t0
        failed = sum(r.failure is not None for r in records)
        print(f"--jobs {jobs}: {len(records)} submissions in {seconds:.1f} s, "
              f"{60 * len(records) / seconds:.1f} submissions per minute" + (f" ({failed} failed)" if failed else ""))
    if not args.keep:
        shutil.rmtree(root, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
