"""``python -m kit check-data``: the precomputed data the public self-checks read, written in one go.

Some public checks need what only working answers can compute, and answers cannot ship; so the
grader side (solutions/) computes them for the public seed here and the results are committed
next to the checks, which read them.  Tests prove each committed file equals a fresh
computation (tests/judging_tests/test_matching_easy_points.py, tests/judging_tests/test_twisted_pair.py).

- ``starter/checks/matching_goals.json``: Q4.1 and Q4.2's easy points of the public scene
  (the default data's scene, scenes.defaults.default_temple: a small public scene has too little
  relief for a flat temple to be told from the true one) and the goals several correct matcher styles set on them
  (solutions.matching_styles);
- ``starter/checks/twisted_pair.json``: Q3.3's twisted-pair case of the public seed
  (solutions.twisted_pair, made with working linear triangulations);
- ``starter/checks/residual_case.json``: Q5's public rodriguesResidual check, the handout's
  residuals of its inputs' x misread (judging.bundle.misreadings; solutions.expected);
- ``starter/checks/figure_data.json``: what the figures of the default data need of working
  answers (starter.checks.pictures.precomputed; solutions.expected): Q3.3's points under each
  candidate camera, Q5's residuals at the start, Q6's triangulations under three threshold rules.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

__all__ = ["CHECKS_DIR", "FIGURE_FILE", "FILES", "GOALS_FILE", "N_POINTS", "RESIDUAL_FILE", "TWISTED_FILE",
           "compute_figure_data", "compute_residual_case", "compute_goals", "encode", "encode_rows", "encode_twisted_pair",
           "fresh", "main"]

CHECKS_DIR = Path(__file__).resolve().parent.parent / "starter" / "checks"
GOALS_FILE = CHECKS_DIR / "matching_goals.json"
TWISTED_FILE = CHECKS_DIR / "twisted_pair.json"
RESIDUAL_FILE = CHECKS_DIR / "residual_case.json"
FIGURE_FILE = CHECKS_DIR / "figure_data.json"
N_POINTS = 30
_DECIMALS = 9


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


def _numbers(a) -> list:
    """An array as nested lists rounded to _DECIMALS (None where not finite: JSON has no NaN)."""
    a = np.asarray(a, float)
    if a.ndim == 0:
        return round(float(a), _DECIMALS) if np.isfinite(a) else None
    return [_numbers(v) for v in a]


def encode_rows(data: dict) -> str:
    """Like :func:`encode`, with each innermost list of numbers on one line."""
    text = json.dumps(data, indent=1)
    return re.sub(r"\[\s+([^\[\]{}]*?)\s+\]", lambda m: "[" + ", ".join(v.strip() for v in m.group(1).split(",")) + "]",
                  text) + "\n"


def compute_residual_case() -> dict:
    """The JSON-ready residuals of the public rodriguesResidual inputs' x misread, label -> order -> (4N,)."""
    from solutions.expected import residual_case
    from starter.checks._scenes import PUBLIC_SEED, two_view
    from starter.checks.bundle import residual_inputs

    misread = {label: {order: _numbers(r) for order, r in residual_case(*args).misread.items()}
               for label, args in residual_inputs(two_view())}
    return {"made_by": f"solutions.expected.residual_case on starter.checks.bundle.residual_inputs of the public pair "
                       f"(seed {PUBLIC_SEED})", "misread": misread}


def compute_figure_data() -> dict:
    """The JSON-ready data of starter.checks.pictures.precomputed, for the default data in data/."""
    from core.paths import DATA_DIR
    from solutions.expected import candidate_points, residual_case, rule_points
    from starter.checks.pictures.precomputed import digest
    from starter.checks.pictures.public import car, need_truth, temple
    from starter.checks.pictures.q5_problem import problem, start_x
    from starter.checks.pictures.q6_multiview import THRES
    from starter.checks.twisted_pair import public_case

    pub = temple(DATA_DIR)
    s, d = need_truth(pub, "check-data"), pub.data
    case = public_case()
    out = {"made_by": "solutions.expected on the default data (data/) and the twisted-pair case"}
    for name, F, p1, p2, K1, K2 in (("default", s.F_true, d.pts1, d.pts2, d.K1, d.K2),
                                    ("twisted", case.F, case.pts1, case.pts2, case.pair.K1, case.pair.K2)):
        cands = candidate_points(F, p1, p2, K1, K2)
        out[f"q3_3_{name}"] = {"digest": digest(p1, p2, K1, K2), "candidates": [
            {"x": _numbers(c["x"]), "z": _numbers(c["z"]), "front1": [int(v) for v in c["front1"]],
             "front2": [int(v) for v in c["front2"]]} for c in cands]}
    pr = problem(s, d)
    out["q5_start"] = {"digest": digest(pr.p1, pr.p2, pr.K1, pr.K2),
                       "residuals": _numbers(residual_case(pr.K1, pr.M1, pr.p1, pr.K2, pr.p2, start_x(pr)).expected)}
    frame = car(DATA_DIR, truth=False).frame
    out["q6_rules"] = {"digest": digest(*frame.C, *frame.pts), "thres": THRES,
                       "rules": {rule: _numbers(P) for rule, P in rule_points(frame.C, frame.pts, THRES).items()}}
    return out


# file name (in starter/checks/) -> the function making its text
FILES = {
    GOALS_FILE.name: lambda: encode(compute_goals()),
    TWISTED_FILE.name: encode_twisted_pair,
    RESIDUAL_FILE.name: lambda: encode_rows(compute_residual_case()),
    FIGURE_FILE.name: lambda: encode_rows(compute_figure_data()),
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
