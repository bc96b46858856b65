"""``python -m autograder``: grade submissions, write the answer-key submission.

  grade SUBMISSION... --out DIR [--jobs N]   grade folders or .zip files of notebooks into DIR
        [--hidden-dir PATH]                   (with more hidden checks: pytest tests, see autograder/hidden)
  key --out DIR                               write the answer-key submission (scores full marks)

  gradescope ...                              build the Gradescope autograder zip, or run inside it
  nbgrader ...                                build an nbgrader course graded by the hidden checks

The commands are listed in ``COMMANDS``; ``gradescope`` and ``nbgrader`` add their own arguments
(``add_cli`` of their modules).
"""

from __future__ import annotations

import sys
from pathlib import Path

from core.commands import Command
from core.commands import build_parser as _build_parser
from core.commands import run


def _grade(args) -> int:
    from .config import load_config
    from .batch import grade_batch

    config = load_config(args.config)
    if config.is_dev:
        print("warning: grading with the development secret, so the hidden scenes are the public "
              "defaults; set HW4_GRADER_SECRET or HW4_GRADER_CONFIG for real grading", file=sys.stderr)
    records = grade_batch(args.submissions, args.out, jobs=args.jobs, config=config, resume=not args.no_resume,
                          progress=not args.quiet, isolation=args.isolation, extra_tests=args.hidden_dir)
    graded = sum(not r.skipped for r in records)
    failed = [r.name for r in records if r.failure]
    print(f"{len(records)} submissions ({graded} graded now, {len(records) - graded} already done); "
          f"results in {Path(args.out) / '<name>'}, grades in {Path(args.out) / 'grades.csv'}")
    if failed:
        print(f"could not be graded: {', '.join(failed)} (see their feedback.md and grading.json)")
    return 0


def _key(args) -> int:
    from .key import write_key_submission

    path = write_key_submission(args.out, zip_it=not args.no_zip)
    print(f"answer-key submission: {path}")
    if args.grade:
        from .config import load_config
        from .batch import grade_batch

        record = grade_batch([path], Path(args.out) / "graded", config=load_config(args.config),
                             resume=False, progress=False)[0]
        print(f"graded: {record.score:g} points ({record.folder / 'feedback.md'})")
    return 0


def _grade_arguments(p) -> None:
    p.add_argument("submissions", nargs="+", help="submission folders or .zip files")
    p.add_argument("--out", required=True, help="output folder: <out>/<name>/results.json, <out>/grades.csv")
    p.add_argument("--jobs", type=int, default=1, help="submissions graded at once (default 1)")
    p.add_argument("--config", default=None, help="grader settings (JSON; default: $HW4_GRADER_CONFIG)")
    p.add_argument("--no-resume", action="store_true", help="regrade submissions whose results exist")
    p.add_argument("--isolation", default="auto", choices=["auto", "namespaces", "user-namespaces", "basic"],
                   help="sandbox level (default: the strongest that works here)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--hidden-dir", default=None,
                   help="a folder of more hidden checks (pytest test files) to run with the kit's own")


def _key_arguments(p) -> None:
    p.add_argument("--out", required=True, help="folder to write hw4_key/ and hw4_key.zip into")
    p.add_argument("--no-zip", action="store_true", help="only the folder")
    p.add_argument("--grade", action="store_true", help="also grade it and print the score")
    p.add_argument("--config", default=None, help="grader settings for --grade")


# __name__ is "__main__" under python -m and "autograder.__main__" when imported: either way this module.
COMMANDS = {
    "grade": Command(__name__, "_grade", "grade submissions (folders or .zip files of notebooks)",
                     arguments="_grade_arguments"),
    "key": Command(__name__, "_key", "write the answer-key submission (a folder and a .zip)",
                   arguments="_key_arguments", needs=("nbformat",), install="pip install nbformat"),
    "gradescope": Command("autograder.gradescope", help="build the Gradescope autograder zip, or run inside it",
                          register="add_cli"),
    "nbgrader": Command("autograder.nbgrader_course", help="build an nbgrader course graded by the hidden checks",
                        register="add_cli"),
}


def build_parser():
    """The parser with every command and its arguments (every command's module imported)."""
    return _build_parser("python -m autograder", __doc__, COMMANDS)


def main(argv=None) -> int:
    return run("python -m autograder", __doc__, COMMANDS, argv)


if __name__ == "__main__":
    sys.exit(main())
