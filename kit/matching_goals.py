"""``python -m kit matching-goals``: the public self-check's easy points and goals of Q4.1 and Q4.2.

The matcher styles that set the goal are working answers to Q4.1 (solutions.matching_styles) and
cannot ship, so the goals of the public scene (starter.checks._scenes.temple_scene) are computed
here and committed as ``starter/checks/matching_goals.json``, which the self-check reads; a test
proves the committed file equals a fresh computation.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ["GOALS_FILE", "N_POINTS", "compute_goals", "main"]

GOALS_FILE = Path(__file__).resolve().parent.parent / "starter" / "checks" / "matching_goals.json"
N_POINTS = 30


def compute_goals() -> dict:
    """The JSON-ready goals: rows (of templeCoords in the public scene), tol3d, ref_share, ref_share_3d, styles."""
    from solutions.matching_styles import scene_problem
    from starter.checks._scenes import PUBLIC_SEED, temple_scene

    rows, p = scene_problem(temple_scene(), N_POINTS, None)
    return {"scene": f"starter.checks._scenes.temple_scene() (seed {PUBLIC_SEED})",
            "rows": [int(r) for r in rows],
            "tol3d": [round(float(t), 9) for t in p.tol3d],
            "ref_share": round(p.ref_share, 9), "ref_share_3d": round(p.ref_share_3d, 9),
            "styles": [[name, round(a, 9), round(b, 9)] for name, a, b in p.shares]}


def encode(goals: dict) -> str:
    return json.dumps(goals, indent=1) + "\n"


def add_arguments(p) -> None:
    p.add_argument("--out", default=None, help=f"file to write (default: {GOALS_FILE})")


def main(args) -> int:
    out = Path(args.out) if getattr(args, "out", None) else GOALS_FILE
    out.write_text(encode(compute_goals()), encoding="utf-8")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    import argparse

    raise SystemExit(main(argparse.Namespace(out=None)))
