"""The review's two passes on a class of 300: look-alike code and the class report.

    python benchmarks/review.py [--count 300] [--grade] [--keep DIR]

Generates ``--count`` synthetic submissions (one notebook each, every homework function taken
from the answer key or the review corpus and disguised: variables renamed, comments added) and
``--count`` synthetic graded results (Gradescope results.json with random passes and named
mistakes), then times ``python -m autograder.review similar`` and ``report`` on them (in-process),
and the library-call scan of the submissions (which the report and a grade run's summary.md do).
With ``--grade``, also times grading the answer key once with ``python -m autograder grade``
(one submission, default settings) to set the figures beside the cost of grading.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from anywhere without installing
from core.paths import KIT_ROOT  # noqa: E402

MISTAKES = {"Q2": ["F transposed", "rank 2 not enforced", "F not unscaled"], "Q3.1": ["K1 and K2 swapped in E"],
            "Q3.2": ["error not the sum of squares"], "Q3.3": ["wrong camera of the four"],
            "Q4.1": ["x and y swapped"], "Q5": ["residuals in another layout"], "Q6": ["detections at exactly Thres used"]}


def _disguise(source: str, rng: np.random.Generator) -> str:
    """Rename assigned variables with a random suffix and sprinkle comments."""
    names = set(re.findall(r"^\s+([A-Za-z_]\w*)\s*=", source, re.MULTILINE))
    for n in names:
        source = re.sub(rf"\b{n}\b", f"{n}_{rng.integers(100)}", source)
    lines = source.split("\n")
    out = []
    for line in lines:
        out.append(line)
        if line.strip() and rng.random() < 0.1 and not line.rstrip().endswith(("(", "[", ",", "\\")):
            out[-1] = line + "  # note"
    return "\n".join(out)


def make_submissions(folder: Path, count: int, rng: np.random.Generator) -> list[Path]:
    import nbformat

    from autograder.review.reader import FUNCTIONS, read_submission

    pools: dict[str, list[str]] = {f: [] for f in FUNCTIONS}
    for src in [KIT_ROOT / "notebooks" / "key", *sorted((KIT_ROOT / "tests" / "review_corpus").glob("*.py"))]:
        for f, fs in read_submission(src).functions.items():
            pools[f].append(fs.source)
    paths = []
    for k in range(count):
        nb = nbformat.v4.new_notebook()
        nb.cells = [nbformat.v4.new_code_cell("import numpy as np")]
        for f, pool in pools.items():
            if pool and rng.random() < 0.95:
                nb.cells.append(nbformat.v4.new_code_cell(_disguise(pool[rng.integers(len(pool))], rng)))
        target = folder / f"student{k:03d}"
        target.mkdir(parents=True)
        nbformat.write(nb, target / "q3_metric_reconstruction.ipynb")
        paths.append(target)
    return paths


def make_results(folder: Path, count: int, rng: np.random.Generator) -> None:
    from autograder.feedback.results import QuestionResult, SubmissionResult, TestResult, autograded_question_ids, write_csv
    from core.manifest import question

    results = []
    for k in range(count):
        qs = []
        for qid in autograded_question_ids():
            pts = question(qid).points
            tests = []
            for t in range(3):
                ok = rng.random() < 0.8
                m = MISTAKES.get(qid, [None])[rng.integers(len(MISTAKES.get(qid, [None])))]
                fb = f"off by 3 px. Likely mistake: {m}. Fix it." if (m and not ok) else "wrong"
                tests.append(TestResult.check(f"check {t}", ok, pts / 3, fb))
            qs.append(QuestionResult.of(qid, tests))
        r = SubmissionResult(tuple(qs), student_id=f"student{k:03d}")
        (folder / r.student_id).mkdir(parents=True)
        r.write_gradescope(folder / r.student_id / "results.json")
        results.append(r)
    write_csv(folder / "grades.csv", results)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--count", type=int, default=300)
    ap.add_argument("--grade", action="store_true", help="also time grading the answer key once")
    ap.add_argument("--keep", default=None, help="write everything here instead of a temp folder")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(12)
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(args.keep or tmp)
        t0 = time.perf_counter()
        subs = make_submissions(base / "submissions", args.count, rng)
        make_results(base / "graded", args.count, rng)
        print(f"generated {args.count} submissions and {args.count} results in {time.perf_counter() - t0:.1f} s")

        from autograder.review.__main__ import run_similar
        from autograder.review.report import write_report

        done = run_similar(subs, base / "similar", top=20)
        print(f"similarity pass, {args.count} submissions x 10 functions: {done['seconds_total']:.2f} s "
              f"(reading {done['seconds_read']:.2f} s, fingerprints and comparison {done['seconds_compare']:.2f} s, "
              f"{done['flagged']} pairs flagged: the synthetic class is built from a few templates)")
        t0 = time.perf_counter()
        write_report(base / "graded", base / "report")
        print(f"class report, {args.count} results: {time.perf_counter() - t0:.2f} s")
        from autograder.review.library_calls import find_in_class

        t0 = time.perf_counter()
        found = find_in_class([(p.name, p) for p in subs])
        print(f"library calls (summary.md and the class report read each submission's code once), "
              f"{args.count} submissions: {time.perf_counter() - t0:.2f} s, "
              f"{sum(bool(calls) for calls, _ in found.values())} with calls")
        if args.grade:
            key = subprocess.run([sys.executable, "-m", "autograder", "key", "--out", str(base / "key")], check=False,
                           cwd=KIT_ROOT, capture_output=True, text=True)
            if key.returncode != 0:
                print("grading not timed: python -m autograder key failed:", key.stderr.strip().splitlines()[-1:])
                return 0
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "autograder", "grade", str(base / "key" / "hw4_key.zip"),
                            "--out", str(base / "key_graded"), "--quiet"], check=True, cwd=KIT_ROOT)
            one = time.perf_counter() - t0
            print(f"grading the answer key once: {one:.1f} s, so about {one * args.count / 60:.0f} min for "
                  f"{args.count} submissions one at a time")
    return 0


if __name__ == "__main__":
    sys.exit(main())
