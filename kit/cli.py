"""The arguments and entry functions of ``python -m kit run`` and ``python -m kit data``."""

from __future__ import annotations


def pipeline_arguments(p) -> None:
    p.add_argument("--data", default=None, help="data folder (default: $HW4_DATA or the kit's data/)")
    p.add_argument("--out", default="out", help="folder for the figures (default: out/)")
    p.add_argument("--seed", type=int, default=0, help="seed of the RANSAC Generator")
    p.add_argument("--tol", type=float, default=1.0, help="RANSAC inlier threshold in pixels")


def run_pipeline(args) -> int:
    """``python -m kit run``: the reference pipeline on a data folder, figures into ``--out``."""
    from kit.pipeline import run

    run(args.data, args.out, seed=args.seed, tol=args.tol)
    return 0


def data_arguments(p) -> None:
    p.add_argument("--out", default=None, help="folder to write (default: the kit's data/)")


def write_data(args) -> int:
    """``python -m kit data``: regenerate the default data folder."""
    from scenes.defaults import write_default_data

    for path in write_default_data(args.out):
        print(f"wrote {path}")
    return 0
