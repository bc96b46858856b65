"""``python -m kit check-data``: the precomputed data the public self-checks read, written in one go.

Some public checks need what only working answers can compute, and answers cannot ship; so the
grader side (solutions/) computes them for the public seed here and the results are committed
next to the checks, which read them.  Tests prove each committed file equals a fresh
computation (tests/test_matching_easy_points.py, tests/test_twisted_pair.py).

- ``starter/checks/matching_goals.json``: Q4.1 and Q4.2's easy points of the public scene
  (the default data's scene, scenes.defaults.default_temple: a small public scene has too little
  relief for a flat temple to be told from the true one) and the goals several correct matcher styles set on them
  (solutions.matching_styles);
- ``starter/checks/twisted_pair.json``: Q3.3's twisted-pair case of the public seed
  (solutions.twisted_pair, made with working linear triangulations).
"""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["CHECKS_DIR", "FILES", "GOALS_FILE", "N_POINTS", "TWISTED_FILE", "compute_goals", "encode",
           "encode_twisted_pair", "fresh", "main"]

CHECKS_DIR = Path(__file__).resolve().parent.parent / "starter" / "checks"
GOALS_FILE = CHECKS_DIR / "matching_goals.json"
TWISTED_FILE = CHECKS_DIR / "twisted_pair.json"
N_POINTS = 30


def compute_goals() -> dict:
    """The JSON-ready goals: rows (of templeCoords in the public scene), tol3d, ref_share, ref_share_3d, flat_share_3d, styles."""
    from solutions.matching_styles import scene_problem
    from scenes.defaults import TEMPLE_SEED, default_temple

    rows, p = scene_problem(default_temple(), N_POINTS, None)
    return {"scene": f"scenes.defaults.default_temple() (seed {TEMPLE_SEED})",
            "rows": [int(r) for r in rows],
            "tol3d": [round(float(t), 9) for t in p.tol3d],
            "ref_share": round(p.ref_share, 9), "ref_share_3d": round(p.ref_share_3d, 9),
            "flat_share_3d": round(p.flat_share_3d, 9),
            "styles": [[name, round(a, 9), round(b, 9)] for name, a, b in p.shares]}


def encode(goals: dict) -> str:
    return json.dumps(goals, indent=1) + "\n"


def encode_twisted_pair() -> str:
    """The text of twisted_pair.json: the public seed's case (starter.checks.twisted_pair.encode)."""
    from solutions.twisted_pair import twisted_pair_case
    from starter.checks._scenes import PUBLIC_SEED
    from starter.checks.twisted_pair import encode as encode_case

    return encode_case(twisted_pair_case(PUBLIC_SEED),
                       made_by=f"solutions.twisted_pair.twisted_pair_case({PUBLIC_SEED}) (the public seed)")


# file name (in starter/checks/) -> the function making its text
FILES = {
    GOALS_FILE.name: lambda: encode(compute_goals()),
    TWISTED_FILE.name: encode_twisted_pair,
}


def fresh(name: str) -> str:
    """The text of the data file ``name`` (a key of FILES), computed now."""
    if name not in FILES:
        raise ValueError(f"name: expected one of {sorted(FILES)}, got {name!r}")
    return FILES[name]()


def add_arguments(p) -> None:
    p.add_argument("--out", default=None, help=f"folder to write the files into (default: {CHECKS_DIR})")
    p.add_argument("--only", choices=sorted(FILES), action="append", default=None,
                   help="write only this file (repeatable; default: all of them)")


def main(args) -> int:
    out = Path(args.out) if getattr(args, "out", None) else CHECKS_DIR
    if not out.is_dir():
        raise FileNotFoundError(f"--out: no folder {out}")
    for name in getattr(args, "only", None) or FILES:
        (out / name).write_text(fresh(name), encoding="utf-8")
        print(f"wrote {out / name}")
    return 0


if __name__ == "__main__":
    import argparse

    raise SystemExit(main(argparse.Namespace(out=None, only=None)))
