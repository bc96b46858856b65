"""Grading throughput, and what faults in a class cost, in one run each.

    python benchmarks/grading.py [--count 20] [--quick] [--keep DIR]
    python benchmarks/grading.py --class-of [N] [--faults K] [--jobs 2] [--quick]

Throughput: --count submissions graded with --jobs 1 and with --jobs 2, in submissions per minute.
The submissions are the answer key and the corpus of tests/support/corpus (mistakes, valid alternatives,
broken notebooks; the hostile ones are left out, they measure the sandbox rather than a class),
repeated until there are --count.  Settings: the grader's defaults (``GradingConfig()``, the dev
secret) or, with --quick, the small ones of the kit's tests.  The hidden inputs are made once,
before the clock starts, as a real batch does; their cost is printed on its own, and so is the
time of grading the answer key alone.  The batches run without their canary (the answer key graded
first, once per batch), whose cost is printed on its own too: the figures are those of grading.

Faults (--class-of, N = 10 when not given): a class of N graded as a TA would (--jobs 2, canary
on) twice in the same run, first clean, then with K infinite loops and K memory bombs in place of
K + K of its answer keys (K = 1 per 15 submissions, at least 1, unless --faults).  It prints each
class's time, the seconds of each submission that differs between the two, and the ratio of the
faulty class to the clean one against the goal (at most ``FAULT_GOAL``).  Other jobs on a shared
machine move that ratio more than the faults do, so it also prints the load average before each
class, the ratio at equal load (how much slower the submissions the two classes share were graded
in the faulty one) and the ratio of CPU seconds.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from anywhere without installing
from core.paths import KIT_ROOT  # noqa: E402
sys.path.insert(0, str(KIT_ROOT / "tests" / "support"))

_HOSTILE = ("bomb", "loop", "exit", "process_left", "patched", "always_true", "reads_grader", "writes_results",
            "prints_fake")
LOOP = "infinite_loop_in_rodriguesResidual_loses_part_of_Q5"
BOMB = "memory_bomb_in_eightpoint_loses_Q2"
FAULT_GOAL = 1.2    # a faulty class's time, at most this multiple of the same class without its faults


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--count", type=int, default=20, help="submissions per run (default 20)")
    ap.add_argument("--quick", action="store_true", help="the small settings of the kit's tests")
    ap.add_argument("--keep", default=None, help="write the submissions and results here instead of a temp folder")
    ap.add_argument("--class-of", type=int, nargs="?", const=10, default=0, metavar="N",
                    help="instead: a class of N (default 10) graded clean, then with infinite loops and memory "
                         "bombs, as a TA would (--jobs 2, canary on); prints the ratio of the two")
    ap.add_argument("--faults", type=int, default=None, metavar="K",
                    help="with --class-of: K infinite loops and K memory bombs (default 1 per 15 submissions, "
                         "at least 1)")
    ap.add_argument("--jobs", type=int, default=2, help="with --class-of: grading jobs (default 2)")
    args = ap.parse_args(argv)

    import corpus

    from autograder.inputs.config import GradingConfig, quick_config
    from autograder.inputs.build import build_hidden_inputs

    config = quick_config() if args.quick else GradingConfig()
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="hw4-grading-bench-"))
    names = ["key_full_marks"] + [n for n in corpus.CASES
                                  if n != "key_full_marks" and not any(h in n for h in _HOSTILE)]

    t0 = time.perf_counter()
    build_hidden_inputs(config)
    print(f"hidden inputs: {time.perf_counter() - t0:.1f} s (once per batch)")
    try:
        if args.class_of:
            return faults(args, config, names, root)
        return throughput(args, config, names, root)
    finally:
        if not args.keep:
            shutil.rmtree(root, ignore_errors=True)


def faults(args, config, names, root: Path) -> int:
    """The same class graded clean, then with its faults; prints both and their ratio."""
    import corpus

    from autograder.channels.batch import grade_batch

    k = args.faults if args.faults is not None else max(1, round(args.class_of / 15))
    if not 0 < 2 * k <= args.class_of:
        raise SystemExit(f"--faults: expected 1 to {args.class_of // 2} for a class of {args.class_of}, got {k}")
    # The faults come first, as a class's order would put them anywhere: here their cost overlaps
    # the rest of the class instead of adding a tail to it.
    hostile = [LOOP] * k + [BOMB] * k
    rest = [names[i % len(names)] for i in range(args.class_of - len(hostile))]
    classes = {"clean": ["key_full_marks"] * len(hostile) + rest, "faulty": hostile + rest}
    seconds, cpu, records = {}, {}, {}
    for which, members in classes.items():
        paths = [corpus.build(n, root / which / f"{i:02d}") for i, n in enumerate(members)]
        print(f"load average before the {which} class: {_load()}", flush=True)
        t0, c0 = time.perf_counter(), _cpu()
        records[which] = grade_batch(paths, root / f"{which}-out", jobs=args.jobs, config=config, resume=False,
                                     progress=False)
        seconds[which], cpu[which] = time.perf_counter() - t0, _cpu() - c0
        failed = sum(r.failure is not None for r in records[which])
        print(f"{which} class of {len(paths)} at --jobs {args.jobs} (canary on): {seconds[which]:.1f} s, "
              f"{cpu[which]:.1f} CPU s" + (f" ({failed} failed)" if failed else ""), flush=True)
    print(f"load average after: {_load()}")
    print("the submissions that differ (seconds each, as its worker graded it):")
    for i, name in enumerate(hostile):
        clean, faulty = records["clean"][i], records["faulty"][i]
        print(f"  {i:2d} {name:55s} {faulty.seconds:6.1f} s, {faulty.score:g} points; "
              f"the answer key in its place {clean.seconds:6.1f} s")
    same = range(len(hostile), args.class_of)
    if same:
        print("  the other {} (the same in both): {:.1f} s in the clean class, {:.1f} s in the faulty one".format(
            len(same), sum(records["clean"][i].seconds for i in same),
            sum(records["faulty"][i].seconds for i in same)))
        # Other jobs on the machine change between the two classes, and the ratio with them; within
        # one class they weigh on every submission alike.  So the shared submissions' seconds say how
        # much slower the machine was for the faulty class (L), and the ratio is given at equal load too.
        load = sum(records["faulty"][i].seconds for i in same) / sum(records["clean"][i].seconds for i in same)
        extra = sum(records["faulty"][i].seconds - load * records["clean"][i].seconds for i in range(len(hostile)))
        print(f"  the machine was {load:.2f}x as slow for the faulty class (the shared submissions); at equal "
              f"load the faults took {extra:+.1f} s beyond the answer keys, and faulty / clean is "
              f"{seconds['faulty'] / (load * seconds['clean']):.2f}x")
    # CPU seconds move less than wall-clock ones when other jobs share the machine; a fault that
    # waits instead of computing costs wall-clock time only.
    print(f"CPU seconds, faulty / clean: {cpu['faulty'] / cpu['clean']:.2f}x")
    ratio = seconds["faulty"] / seconds["clean"]
    print(f"faulty / clean ({k} infinite loop{'s' * (k > 1)}, {k} memory bomb{'s' * (k > 1)} in {args.class_of}): "
          f"{seconds['faulty']:.1f} s / {seconds['clean']:.1f} s = {ratio:.2f}x "
          f"(goal: at most {FAULT_GOAL}x): {'met' if ratio <= FAULT_GOAL else 'MISSED'}")
    return 0


def throughput(args, config, names, root: Path) -> int:
    """Submissions per minute at --jobs 1 and 2, beside the answer key alone and the canary's cost."""
    import corpus

    from autograder.channels.batch import grade_batch

    paths = [corpus.build(names[k % len(names)], root / "subs" / f"{k:02d}") for k in range(args.count)]
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
    return 0


def _cpu() -> float:
    """CPU seconds of this process and of every process it started that has ended (the grading
    workers and, through them, the sandboxes' children)."""
    own, ended = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + ended.ru_utime + ended.ru_stime


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


if __name__ == "__main__":
    sys.exit(main())
