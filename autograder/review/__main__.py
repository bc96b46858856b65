"""``python -m autograder.review similar|report ...``: the commands of the review package.

similar SUBMISSIONS... --out DIR [--top N] [--keep-starter]
    Look-alike code per homework function.  SUBMISSIONS are submission folders or zips, or class
    folders holding them.  Writes DIR/similarity.csv, DIR/similarity.json, DIR/similarity.html
    (DIR 0700, its files 0600: they hold every student's code); the flagged pairs are also joined
    into groups (N copies of one solution: one group of N).  Names and notes pass
    ``core.untrusted`` for each file (``for_csv_cell``, ``for_json``, ``for_html``).
report GRADED_DIR --out DIR [--assignment NAME] [--roster CANVAS_EXPORT.csv] [--per-question] [--config FILE]
    The class report of a graded folder (see autograder.review.report); the library calls it lists
    are the grader config's ``library_calls`` (default: autograder.review.library_calls).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from core.text import private_folder, write_atomic
from core.untrusted import csv_text, for_json, for_terminal

_PRIVATE = 0o600

__all__ = ["main", "expand_submissions", "run_similar"]


def expand_submissions(paths) -> list[Path]:
    """The submissions among ``paths``: a folder holding only folders and zips is a class folder."""
    out = []
    for p in map(Path, paths):
        if not p.exists():
            raise ValueError(f"SUBMISSIONS: expected existing folders or zips, got {str(p)!r}")
        if p.is_dir():
            children = [c for c in sorted(p.iterdir()) if not c.name.startswith(".")]
            has_code = any(c.is_file() and c.suffix in (".ipynb", ".py") for c in children)
            subs = [c for c in children if c.is_dir() or c.suffix == ".zip"]
            if subs and not has_code:
                out.extend(subs)
                continue
        out.append(p)
    return out


def run_similar(paths, out: str | Path, *, top: int = 20, keep_starter: bool = False) -> dict:
    """Read, compare and write; return the written paths and the timings."""
    from .html import similarity_page
    from .reader import read_submission
    import numpy as np

    from .similarity import FLAG, compare, given_hashes, groups

    t0 = time.perf_counter()
    subs = [read_submission(p) for p in expand_submissions(paths)]
    names = [s.name for s in subs]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise ValueError(f"SUBMISSIONS: expected distinct submission names, got {dupes} more than once")
    t1 = time.perf_counter()
    given = set() if keep_starter else given_hashes()
    comps = compare(subs, given)
    t2 = time.perf_counter()
    out = private_folder(out)
    ranked = {f: c.ranked(top) for f, c in comps.items()}
    found = groups(comps)
    group_of = {name: k for k, g in enumerate(found, start=1) for name in g.members}
    rows = [["function", "rank", "a", "b", "score", "jaccard", "containment", "shared", "look_at", "group"]]
    for f, pairs in ranked.items():
        for p in pairs:
            d = p.as_dict()
            rows.append([f, d["rank"], d["a"], d["b"], d["score"], d["jaccard"], d["containment"], d["shared"],
                         "look at these" if p.flagged else "", group_of.get(p.a, "") if p.flagged else ""])
    write_atomic(out / "similarity.csv", csv_text(rows), mode=_PRIVATE)
    # Submission names and notes are the students' (folder and file names): every string is made
    # visible, as in the CSV and the page.
    write_atomic(out / "similarity.json", json.dumps(for_json({
        "submissions": names,
        "groups": [g.as_dict() for g in found],
        "functions": {f: {"compared": comps[f].names, "without_own_code": comps[f].skipped,
                          "pairs": [p.as_dict() for p in pairs]} for f, pairs in ranked.items()},
        "notes": {s.name: list(s.notes) for s in subs if s.notes},
    }), indent=1), mode=_PRIVATE)
    sources = {(s.name, f): fs for s in subs for f, fs in s.functions.items()}
    write_atomic(out / "similarity.html", similarity_page(comps, sources, top=min(top, 10), groups=found),
                 mode=_PRIVATE)
    return {"csv": out / "similarity.csv", "json": out / "similarity.json", "html": out / "similarity.html",
            "submissions": len(subs), "flagged": sum(int(np.sum(np.triu(c.score >= FLAG, 1))) for c in comps.values()),
            "groups": found,
            "seconds_read": t1 - t0, "seconds_compare": t2 - t1, "seconds_total": time.perf_counter() - t0}


def similar_arguments(p) -> None:
    p.add_argument("submissions", nargs="+")
    p.add_argument("--out", required=True)
    p.add_argument("--top", type=int, default=20,
                   help="pairs listed per function (and beyond, the flagged pairs linking each group)")
    p.add_argument("--keep-starter", action="store_true", help="do not subtract the handout's code")


def report_arguments(p) -> None:
    p.add_argument("graded")
    p.add_argument("--out", required=True)
    p.add_argument("--assignment", default="HW4 autograded", help="the Canvas assignment column's name")
    p.add_argument("--roster", help="a Canvas gradebook export, to fill Student, ID, SIS User ID and Section")
    p.add_argument("--per-question", action="store_true", help="one Canvas column per question too")
    p.add_argument("--config", default=None,
                   help="grader settings (JSON; default: $HW4_GRADER_CONFIG): its library_calls are the library "
                        "functions listed for the staff")


def similar_command(args) -> int:
    done = run_similar(args.submissions, args.out, top=args.top, keep_starter=args.keep_starter)
    print(f"{done['submissions']} submissions compared in {done['seconds_total']:.1f} s; "
          f"{done['flagged']} pair(s) to look at, in {len(done['groups'])} group(s).")
    for g in done["groups"]:
        print(f"  {len(g.members)}: {for_terminal(', '.join(g.members))} ({', '.join(g.functions)})")
    for k in ("csv", "json", "html"):
        print(f"  {for_terminal(done[k])}")
    return 0


def report_command(args) -> int:
    from autograder.inputs.config import load_config

    from .report import write_report

    t0 = time.perf_counter()
    written = write_report(args.graded, args.out, assignment=args.assignment, roster=args.roster,
                           per_question=args.per_question, library_calls=load_config(args.config).library_names())
    print(f"class report written in {time.perf_counter() - t0:.1f} s:")
    for k in ("html", "tests", "mistakes", "grades", "canvas", "library_calls"):
        print(f"  {for_terminal(written[k])}")
    return 0


def main(argv=None) -> int:
    """``python -m autograder.review similar|report ...`` (also ``python -m autograder similar|report``)."""
    parser = argparse.ArgumentParser(prog="python -m autograder.review", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    similar_arguments(sub.add_parser("similar", help="look-alike code per homework function"))
    report_arguments(sub.add_parser("report", help="the class report of a graded folder"))
    args = parser.parse_args(argv)
    try:
        return similar_command(args) if args.command == "similar" else report_command(args)
    except (FileNotFoundError, ValueError) as exc:  # as core.commands does for python -m autograder
        print(f"error: {for_terminal(exc)}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
