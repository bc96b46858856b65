"""``python -m kit``: the kit's commands for instructors and students.

  run        the whole pipeline with the reference solutions on a data folder (the main job)
  data       regenerate the default data/ from the seeded scene generator
  notebooks  build the student notebooks, the answer key and the nbgrader source from solutions/
  release    write the student release (no solutions, no answer key, no autograder)
  pdf        a student's notebooks -> one Gradescope-ready PDF (and the code bundle)
"""

from __future__ import annotations

import argparse
import sys


def _run(args) -> int:
    try:
        from .pipeline import run
    except ImportError:  # the student release has no reference solutions to run
        print("error: `run` needs the reference solutions, which the student release does not include",
              file=sys.stderr)
        return 2

    run(args.data, args.out, seed=args.seed, tol=args.tol)
    return 0


def _data(args) -> int:
    from scenes.defaults import write_default_data

    for path in write_default_data(args.out):
        print(f"wrote {path}")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m kit", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("run", help="run the reference pipeline on a data folder and write its figures")
    p.add_argument("--data", default=None, help="data folder (default: $HW4_DATA or the kit's data/)")
    p.add_argument("--out", default="out", help="folder for the figures (default: out/)")
    p.add_argument("--seed", type=int, default=0, help="seed of the RANSAC Generator")
    p.add_argument("--tol", type=float, default=1.0, help="RANSAC inlier threshold in pixels")
    p.set_defaults(func=_run)

    p = sub.add_parser("data", help="regenerate the default data folder from the scene generator")
    p.add_argument("--out", default=None, help="folder to write (default: the kit's data/)")
    p.set_defaults(func=_data)

    for module in ("notebooks", "release", "pdf"):
        try:
            mod = __import__(f"kit.{module}", fromlist=["add_cli"])
        except ImportError:
            continue
        if hasattr(mod, "add_cli"):
            mod.add_cli(sub)

    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
