"""``python -m autograder``: grade submissions, write the answer-key submission.

  grade SUBMISSION... --out DIR [--jobs N]   grade folders or .zip files of notebooks into DIR
  key --out DIR                               write the answer-key submission (scores full marks)

Other modules of the package add their own subcommands through an ``add_cli(subparsers)``
function (``autograder.gradescope``, ``autograder.nbgrader_course``) when they are present.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

_PLUGINS = ("gradescope", "nbgrader_course")


def _grade(args) -> int:
    from .config import load_config
    from .grade import grade_batch

    config = load_config(args.config)
    if config.is_dev:
        print("warning: grading with the development secret, so the hidden scenes are the public "
              "defaults; set HW4_GRADER_SECRET or HW4_GRADER_CONFIG for real grading", file=sys.stderr)
    records = grade_batch(args.submissions, args.out, jobs=args.jobs, config=config, resume=not args.no_resume,
                          progress=not args.quiet, isolation=args.isolation)
    graded = sum(not r.skipped for r in records)
    failed = [r.name for r in records if r.failure]
    print(f"{len(records)} submissions ({graded} graded now, {len(records) - graded} already done); "
          f"results in {Path(args.out) / '<name>'}, grades in {Path(args.out) / 'grades.csv'}")
    if failed:
        print(f"could not be graded: {', '.join(failed)} (see their feedback.md and grading.json)")
    return 0


def _key(args) -> int:
    from .grade import write_key_submission

    path = write_key_submission(args.out, zip_it=not args.no_zip)
    print(f"answer-key submission: {path}")
    if args.grade:
        from .config import load_config
        from .grade import grade_batch

        record = grade_batch([path], Path(args.out) / "graded", config=load_config(args.config),
                             resume=False, progress=False)[0]
        print(f"graded: {record.score:g} points ({record.folder / 'feedback.md'})")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m autograder", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("grade", help="grade submissions (folders or .zip files of notebooks)")
    p.add_argument("submissions", nargs="+", help="submission folders or .zip files")
    p.add_argument("--out", required=True, help="output folder: <out>/<name>/results.json, <out>/grades.csv")
    p.add_argument("--jobs", type=int, default=1, help="submissions graded at once (default 1)")
    p.add_argument("--config", default=None, help="grader settings (JSON; default: $HW4_GRADER_CONFIG)")
    p.add_argument("--no-resume", action="store_true", help="regrade submissions whose results exist")
    p.add_argument("--isolation", default="auto", choices=["auto", "namespaces", "user-namespaces", "basic"],
                   help="sandbox level (default: the strongest that works here)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_grade)

    p = sub.add_parser("key", help="write the answer-key submission (a folder and a .zip)")
    p.add_argument("--out", required=True, help="folder to write hw4_key/ and hw4_key.zip into")
    p.add_argument("--no-zip", action="store_true", help="only the folder")
    p.add_argument("--grade", action="store_true", help="also grade it and print the score")
    p.add_argument("--config", default=None, help="grader settings for --grade")
    p.set_defaults(func=_key)

    for name in _PLUGINS:
        try:
            module = importlib.import_module(f"autograder.{name}")
        except ImportError:
            continue
        if hasattr(module, "add_cli"):
            module.add_cli(sub)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
