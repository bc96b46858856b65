"""``python -m autograder``: grade submissions, write the answer-key submission.

  grade SUBMISSION... --out DIR [--jobs N]   grade folders or .zip files of notebooks into DIR
        [--hidden-dir PATH]                   (with more hidden checks: pytest tests, see autograder/hidden)
        [--official-data DIR]                 (also on the official course data; never unless asked)
        [--regrade NAME...] [--regrade-all]   (grade these students again / everyone, even into a folder
                                              of another configuration)
        [--regrade-into NEW_DIR]              (grade again beside DIR and write regrade_diff.* in NEW_DIR)
  regrade OLD_DIR --into NEW_DIR [SUB...]     the same: grade OLD_DIR's class again, with the diff
  accept NEW_DIR --into OLD_DIR               publish a regrade (OLD_DIR's results kept in .history/)
  key --out DIR                               write the answer-key submission (scores full marks)
  similar SUBMISSION... --out DIR             look-alike code: pairs of submissions to look at, per function
  report GRADED_DIR --out DIR                 the class report: pass shares, mistakes, histograms, Canvas CSV
  nbgrader-grade COURSE [--assignment hw4]    write the kit's scores into an nbgrader gradebook (after autograde)

On a cluster (docs/cluster.md; autograder.channels.cluster):
  prepare SUBMISSION... --root ROOT --shards K   hidden inputs, the canary and the frozen manifest in ROOT
  grade --shard i/K --out ROOT                shard i of K: the manifest's submissions i, i+K, ...
  shards ROOT                                 each shard's progress, and the shards to resubmit
  merge ROOT                                  the shards joined into ROOT/out (grades.csv, summary.md),
                                              the class report and the look-alike check
  slurm ROOT / kubernetes ROOT --image I --claim PVC   the jobs of the shards still to do, and the merge

Before grading anything, a batch grades the answer key in its own sandbox and configuration (the
canary): unless the key gets full marks, nothing is graded and the command says why.  Student code
never runs as root or as the grader's own user unless --allow-weak-isolation is given.

A batch resumes: results of the same content and configuration are kept; failures, internal
errors and submissions that were in flight when a grader died are graded again.  Ctrl-C stops it
(grades.csv written for what finished; a second Ctrl-C exits at once).  An --out folder holds one
configuration (grader and kit version, secret, data, settings, hidden tests): another is refused.

  gradescope ...                              build the Gradescope autograder zip, or run inside it
  nbgrader ...                                build an nbgrader course graded by the hidden checks

The commands are listed in ``COMMANDS``; ``gradescope`` and ``nbgrader`` add their own arguments
(``add_cli`` of their modules).
"""

from __future__ import annotations

import atexit
import os
import signal
import sys
from pathlib import Path

from core.commands import Command
from core.commands import build_parser as _build_parser
from core.commands import run
from core.untrusted import for_terminal

from .sandbox.model import LEVELS


def _config(args):
    from autograder.inputs.config import load_config

    config = load_config(args.config, official_data=args.official_data)
    if config.is_dev:
        print("warning: grading with the development secret, so the hidden scenes are the public "
              "defaults; set HW4_GRADER_SECRET or HW4_GRADER_CONFIG for real grading (summary.md says so)",
              file=sys.stderr)
    if config.official_dir() is not None:
        print(f"grading on the official course data too: {config.official_dir()}", file=sys.stderr)
    return config


def _batch_errors(run):
    """Run ``run()``; a refused folder or Ctrl-C become a message and an exit code."""
    from autograder.channels.batch import BatchInterrupted, ConfigurationMismatch

    try:
        return run()
    except ConfigurationMismatch as exc:
        print(f"error: {for_terminal(exc)}", file=sys.stderr)
        return 2
    except BatchInterrupted as exc:
        signal.signal(signal.SIGINT, lambda *_: os._exit(130))  # everything is recorded: another Ctrl-C just exits
        if exc.setup:
            print("\ninterrupted while setting up: nothing was graded or recorded; run the same command again to "
                  "grade", file=sys.stderr)
        else:
            print(f"\ninterrupted: {len(exc.records)} submissions recorded, {len(exc.cancelled)} cancelled and not "
                  f"recorded ({for_terminal(', '.join(exc.cancelled)) or 'none'}); run the same command again to "
                  "resume", file=sys.stderr)
        # Exit now (clean-ups registered with atexit run; no interpreter shutdown a Ctrl-C could cut).
        sys.stdout.flush()
        sys.stderr.flush()
        atexit._run_exitfuncs()
        os._exit(130)
    except KeyboardInterrupt:
        print("\ninterrupted before any submission was graded", file=sys.stderr)
        return 130


def _private(run):
    """Run ``run()`` with umask 077: results, logs and key copies are the grader's alone (restored after,
    so a program that calls these commands in-process keeps its own umask)."""
    old = os.umask(0o077)
    try:
        return run()
    finally:
        os.umask(old)


def _grade(args) -> int:
    if args.shard:
        from autograder.channels.cluster.cli import shard_command

        return _private(lambda: _batch_errors(lambda: shard_command(args)))
    if not args.submissions:
        print("error: grade: expected SUBMISSION... (or --shard i/K --out ROOT of a prepared class)", file=sys.stderr)
        return 2
    if args.regrade_into:
        return _private(lambda: _regrade_run(args, args.out, args.regrade_into, args.submissions))
    return _private(lambda: _batch_errors(lambda: _grade_run(args)))


def _grade_options(args, config) -> dict:
    return {"jobs": args.jobs, "config": config, "progress": not args.quiet, "isolation": args.isolation,
            "extra_tests": args.hidden_dir, "allow_weak": args.allow_weak_isolation,
            "pictures": not args.no_pictures}


def _grade_run(args) -> int:
    from autograder.channels.batch import grade_batch

    config = _config(args)
    records = grade_batch(args.submissions, args.out, resume=not args.no_resume, regrade=args.regrade or (),
                          regrade_all=args.regrade_all, **_grade_options(args, config))
    graded = sum(not r.skipped for r in records)
    failed = [r.name for r in records if r.failure]
    print(f"{len(records)} submissions ({graded} graded now, {len(records) - graded} already done); "
          f"results in {Path(args.out) / '<name>'}, grades in {Path(args.out) / 'grades.csv'}")
    if failed:
        print(f"could not be graded: {for_terminal(', '.join(failed))} (see their feedback.md and grading.json)")
    if config.is_dev:
        print("graded with the DEVELOPMENT secret: not for publishing")
    return 0


def _regrade(args) -> int:
    return _private(lambda: _regrade_run(args, args.old, args.into, args.submissions or None))


def _regrade_run(args, old, new, paths) -> int:
    from autograder.channels.regrade import regrade

    def run() -> int:
        report = regrade(old, new, paths, **_grade_options(args, _config(args)))
        moved = sorted({c.student for c in report["changes"]})
        print(f"regraded {len(report['records'])} submissions into {new}; {len(moved)} changed score"
              + (f": {for_terminal(', '.join(moved))}" if moved else ""))
        if report["configuration_changes"]:
            print("configuration changes: " + "; ".join(report["configuration_changes"]))
        print(f"diff: {report['files']['md']} (and .csv, .html); publish with: "
              f"python -m autograder accept {new} --into {old}")
        return 0

    return _batch_errors(run)


def _accept(args) -> int:
    from autograder.channels.regrade import accept

    try:
        history = accept(args.new, args.into)
    except ValueError as exc:
        print(f"error: {for_terminal(exc)}", file=sys.stderr)
        return 2
    print(f"published the regrade of {args.new} into {args.into}; the earlier results are in {history}")
    return 0


def _key(args) -> int:
    return _private(lambda: _key_run(args))


def _key_run(args) -> int:
    from autograder.grading.key import write_key_submission


    path = write_key_submission(args.out, zip_it=not args.no_zip)
    print(f"answer-key submission: {path}")
    if args.grade:
        from autograder.inputs.config import load_config
        from autograder.channels.batch import grade_batch

        record = grade_batch([path], Path(args.out) / "graded", config=load_config(args.config),
                             resume=False, progress=False, regrade_all=True)[0]
        print(f"graded: {record.score:g} points ({record.folder / 'feedback.md'})")
    return 0


def _common_arguments(p) -> None:
    p.add_argument("--jobs", type=int, default=1, help="submissions graded at once (default 1)")
    p.add_argument("--config", default=None, help="grader settings (JSON; default: $HW4_GRADER_CONFIG)")
    p.add_argument("--official-data", default=None, metavar="DIR",
                   help="also grade on the official course data in DIR (default: only if $HW4_COURSE_DATA is set)")
    p.add_argument("--isolation", default="auto", choices=["auto", *LEVELS],
                   help="sandbox level (default: the strongest that works here)")
    p.add_argument("--allow-weak-isolation", action="store_true",
                   help="accept a sandbox that runs student code as the grader's own user (refused otherwise)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--no-pictures", action="store_true",
                   help="feedback without the figures of each student's results on the public data "
                        "(they cost a few seconds per submission; scores do not change)")
    p.add_argument("--hidden-dir", default=None,
                   help="a folder of more hidden checks (pytest test files) to run with the kit's own")


def _grade_arguments(p) -> None:
    p.add_argument("submissions", nargs="*", help="submission folders or .zip files")
    p.add_argument("--out", required=True, help="output folder: <out>/<name>/results.json, <out>/grades.csv")
    _common_arguments(p)
    p.add_argument("--shard", default=None, metavar="i/K",
                   help="grade shard i of K of the class prepared in --out (python -m autograder prepare), with "
                        "the manifest's settings")
    p.add_argument("--no-resume", action="store_true", help="regrade submissions whose results exist")
    p.add_argument("--regrade", nargs="+", metavar="NAME", default=None,
                   help="grade these submissions (gradebook names) again, resume the others")
    p.add_argument("--regrade-all", action="store_true",
                   help="grade everything again, even into a folder of another configuration (its results are "
                        "moved to <out>/.superseded-<time>/)")
    p.add_argument("--regrade-into", default=None, metavar="NEW_DIR",
                   help="grade the class of --out again into NEW_DIR and write the diff there (--out untouched)")


def _regrade_arguments(p) -> None:
    p.add_argument("old", help="the published folder of graded results")
    p.add_argument("--into", required=True, help="the new folder (results and regrade_diff.csv/.md/.html)")
    p.add_argument("submissions", nargs="*", help="submissions (default: the ones recorded in OLD's results)")
    _common_arguments(p)


def _prepare(args) -> int:
    from autograder.channels.cluster.cli import prepare_command

    return _private(lambda: _batch_errors(lambda: prepare_command(args, _config(args))))


def _prepare_arguments(p) -> None:
    p.add_argument("submissions", nargs="+", help="submission folders or .zip files")
    p.add_argument("--root", required=True, help="the class's folder on storage every node sees at the same path")
    p.add_argument("--shards", type=int, required=True, help="K: how many shards (jobs) grade the class")
    _common_arguments(p)


def _cluster(function: str):
    """A function of ``autograder.channels.cluster.cli`` (imported when called); a command runs with umask 077."""
    def call(arg):
        from autograder.channels.cluster import cli

        if function.endswith("_arguments"):
            return getattr(cli, function)(arg)
        return _private(lambda: getattr(cli, function)(arg))

    return call


_shards, _merge, _slurm, _kubernetes = (_cluster(f"{n}_command") for n in ("shards", "merge", "slurm", "kubernetes"))
_shards_arguments, _merge_arguments, _slurm_arguments, _kubernetes_arguments = (
    _cluster(f"{n}_arguments") for n in ("shards", "merge", "slurm", "kubernetes"))


def _accept_arguments(p) -> None:
    p.add_argument("new", help="the regrade folder")
    p.add_argument("--into", required=True, help="the published folder it replaces")


def _key_arguments(p) -> None:
    p.add_argument("--out", required=True, help="folder to write hw4_key/ and hw4_key.zip into")
    p.add_argument("--no-zip", action="store_true", help="only the folder")
    p.add_argument("--grade", action="store_true", help="also grade it and print the score")
    p.add_argument("--config", default=None, help="grader settings for --grade")


# __name__ is "__main__" under python -m and "autograder.__main__" when imported: either way this module.
COMMANDS = {
    "grade": Command(__name__, "_grade", "grade submissions (folders or .zip files of notebooks)",
                     arguments="_grade_arguments"),
    "regrade": Command(__name__, "_regrade", "grade a graded class again beside it, with a diff of the scores",
                       arguments="_regrade_arguments"),
    "accept": Command(__name__, "_accept", "publish a regrade: replace the published results with it",
                      arguments="_accept_arguments"),
    "key": Command(__name__, "_key", "write the answer-key submission (a folder and a .zip)",
                   arguments="_key_arguments", needs=("nbformat",), install="pip install nbformat"),
    "gradescope": Command("autograder.channels.gradescope.bundle", help="build the Gradescope autograder zip, or run inside it",
                          register="add_cli"),
    "nbgrader": Command("autograder.channels.nbgrader.course", help="build an nbgrader course graded by the hidden checks",
                        register="add_cli"),
    "nbgrader-grade": Command("autograder.channels.nbgrader.grade", register="add_grade_cli", needs=("nbgrader",),
                              install="pip install 'nbgrader>=0.9.6,<0.10'",
                              help="score an nbgrader course's submissions with the kit's grader (after nbgrader "
                                   "autograde)"),
    "prepare": Command(__name__, "_prepare", "prepare a class for a cluster: hidden inputs, the canary, the manifest",
                       arguments="_prepare_arguments"),
    "shards": Command(__name__, "_shards", "each shard's progress of a prepared class, and the shards to resubmit",
                      arguments="_shards_arguments"),
    "merge": Command(__name__, "_merge", "join the shards of a prepared class: grades.csv, summary.md, the report",
                     arguments="_merge_arguments", needs=("matplotlib",),
                     install="pip install matplotlib"),
    "slurm": Command(__name__, "_slurm", "write the sbatch array of the shards still to do and its merge job",
                     arguments="_slurm_arguments"),
    "kubernetes": Command(__name__, "_kubernetes", "write the Indexed Job of the shards and the merge Job (YAML)",
                          arguments="_kubernetes_arguments", needs=("yaml",),
                          install="pip install pyyaml"),
    "similar": Command("autograder.review.__main__", "similar_command",
                       "rank pairs of submissions whose code looks alike, per function (CSV, JSON, HTML)",
                       arguments="similar_arguments"),
    "report": Command("autograder.review.__main__", "report_command",
                      "the class report of a graded folder: pass shares, named mistakes, histograms, Canvas CSV",
                      arguments="report_arguments", needs=("matplotlib",), install="pip install matplotlib"),
}


def build_parser():
    """The parser with every command and its arguments (every command's module imported)."""
    return _build_parser("python -m autograder", __doc__, COMMANDS)


def main(argv=None) -> int:
    return run("python -m autograder", __doc__, COMMANDS, argv)


HIDDEN_ARGUMENTS = b"[arguments hidden]"


def hide_arguments() -> bool:
    """Blank this process's arguments after the command's name in its ``/proc/<pid>/cmdline``.

    Any process of the machine may read another's command line, sandboxed code at the ``uid``
    level included (there is no pid namespace there): ``python -m autograder grade sub1 sub2 ...``
    would name every submission of the batch, and its output folder.  Python keeps its own copy of
    the arguments (``sys.argv``), so the original strings, which the kernel shows, are overwritten
    in place (as setproctitle does), keeping the last byte NUL so that the kernel reads only this
    area: ``ps`` then shows ``python -m autograder grade [arguments hidden]``.  The grading workers
    get each submission on their stdin, never on a command line.  True when the line changed.
    """
    import ctypes

    try:
        with open("/proc/self/stat", "rb") as fh:
            fields = fh.read().rsplit(b")", 1)[1].split()
        start, end = int(fields[45]), int(fields[46])  # arg_start and arg_end: fields 48 and 49
        with open("/proc/self/cmdline", "rb") as fh:
            shown = fh.read()
    except (OSError, ValueError, IndexError):
        return False
    parts = shown.split(b"\0")[:-1]
    tail = len(sys.argv) - 2  # the arguments after the command's name
    if len(shown) != end - start or tail <= 0 or len(parts) < tail + 2:
        return False  # already rewritten, or nothing to hide
    kept = b"\0".join(parts[:len(parts) - tail]) + b"\0"
    text = kept + HIDDEN_ARGUMENTS + b"\0"
    if len(text) > end - start:
        text = kept
    ctypes.memmove(start, text, len(text))
    ctypes.memset(start + len(text), 0, end - start - len(text))
    return True


if __name__ == "__main__":
    hide_arguments()
    sys.exit(main())
