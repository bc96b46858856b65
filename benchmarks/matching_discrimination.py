"""Whether Q4.1 tells right from wrong on the hidden matching problems, secret by secret.

For each secret of the sweep (``tests/end_to_end/test_secret_sweep.py``'s names, quick settings) the matching
problems are built as the grader builds them (``autograder.inputs.correspondence``), and
matchers are graded on each scene by the hidden test's own call and judgment (``best_match``,
``judging.correspondence.matches``), in this process:

- the correct ones: the real-styles corpus's (tests/support/realstyles: Gaussian-weighted local search,
  whole-line SAD on 0-255 intensities), the sweep's matcher variants (tests/support/corpus/variants.py:
  SAD within 30 rows, its slicing and uint8 habits) and the answer key;
- the wrong ones of the real-styles corpus: the line F^T x1 instead of F x1, and the right line
  searched only within rows y1 +- 10.

The table gives, per secret and scene, the share of the easy points within tolerance of the truth
that the weakest goal style reaches (the goal is 70 % of it), the goal, then for the weakest
correct matcher, the wrong-line matcher and the box matcher the share and the fraction of the
scene's points; the last lines add up each matcher's Q4.1 score out of 15 per secret and name what
of the matching temples is outside ``scenes.envelope``.  Right when every correct matcher keeps
15/15 and both wrong ones at most 7.5/15 under every secret, inside the envelope.

    python benchmarks/matching_discrimination.py [--secrets 20] [--jobs 2]
"""

from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/core.py must not hide core/
from core.paths import KIT_ROOT  # noqa: E402

sys.path.insert(1, str(KIT_ROOT / "tests" / "support"))

from autograder.inputs.config import quick_config  # noqa: E402
from judging import correspondence as jc  # noqa: E402

Q41_POINTS = 15.0


def matchers() -> tuple[dict, dict]:
    """(correct, wrong): name -> epipolarCorrespondence, written as students write them."""
    import solutions
    from corpus import variants
    from realstyles import snippets as s

    def defined(source):
        namespace = {"np": np}
        exec(source, namespace)  # noqa: S102 - the corpus's own sources
        return namespace["epipolarCorrespondence"]

    correct = {"realstyles Gaussian local": defined(s.EC_GAUSS_LOCAL),
               "realstyles whole-line SAD uint8": defined(s.EC_WHOLE_LINE_UINT8),
               "variants SAD": defined(variants.EPIPOLAR_SAD),
               "variants slicing with coordinates": defined(variants.EPIPOLAR_SLICES_WITH_COORDINATES),
               "variants uint8 differences": defined(variants.EPIPOLAR_UINT8_DIFFERENCES),
               "answer key": solutions.epipolarCorrespondence}
    wrong = {"wrong line": defined(s.EC_WRONG_LINE), "small box": defined(s.EC_SMALL_BOX)}
    return correct, wrong


def graded(secret: str) -> list[dict]:
    """One row per scene of ``secret``'s matching problems: the goal and each matcher's share and fraction."""
    from autograder.inputs.correspondence import matching_scenes, prepare_correspondence
    from autograder.hidden.plugin import LocalStudent
    from autograder.inputs.scenes import make_scenes
    from autograder.hidden.test_correspondence import best_match
    from scenes.envelope import outside_envelope

    correct, wrong = matchers()
    config = quick_config(secret=secret)
    scenes = make_scenes(config)
    cases = prepare_correspondence(scenes).cases
    outside = [p for tc, spec in zip(matching_scenes(scenes), config.temples)
               for p in outside_envelope(tc.scene, noise_px=spec.noise_px, label=f"{secret}, {tc.label}")]
    rows = []
    for case in cases:
        row = {"secret": secret, "scene": case.label, "n": len(case.pts1), "tol": case.tol, "outside": outside,
               "ref": case.ref_share, "goal": jc.goal_share(case.ref_share, len(case.pts1)), "results": {}}
        for name, fn in {**correct, **wrong}.items():
            m = best_match(LocalStudent({"epipolarCorrespondence": fn}), case)
            v = jc.matches(m.pts2, case.truth2, case.tol, case.ref_share)
            right = jc.right_2d(m.pts2, case.truth2, case.tol)
            row["results"][name] = (float(right.mean()) if len(right) else 0.0, v.fraction)
        rows.append(row)
    return rows


def report(rows_by_secret: list[list[dict]]) -> tuple[str, bool]:
    """(the table, whether every correct matcher keeps Q4.1 and both wrong ones lose half)."""
    correct, wrong = (list(d) for d in matchers())
    lines = ["| secret | scene | points | weakest goal style | goal | weakest correct | wrong line | small box |",
             "|---|---|---|---|---|---|---|---|"]
    totals: dict[str, list[float]] = {name: [] for name in correct + wrong}
    for rows in rows_by_secret:
        for name in totals:
            totals[name].append(sum(r["results"][name][1] for r in rows) * Q41_POINTS / len(rows))
        for r in rows:
            res = r["results"]
            weakest = min(correct, key=lambda n: (res[n][1], res[n][0]))
            cell = [f"{res[n][0]:.0%} ({res[n][1]:.2f})" for n in (weakest, *wrong)]
            lines.append(f"| {r['secret']} | {r['scene']} | {r['n']} | {r['ref']:.0%} | {r['goal']:.0%} | "
                         f"{cell[0]} {weakest} | {cell[1]} | {cell[2]} |")
    lines.append("")
    lines.append("Q4.1 out of 15 over the secrets (min / max):")
    for name, scores in totals.items():
        lines.append(f"  {name:36s} {min(scores):5.2f} / {max(scores):5.2f}")
    outside = sorted({p for rows in rows_by_secret for r in rows for p in r["outside"]})
    lines.append(f"matching temples outside scenes.envelope: {len(outside)}" + "".join(f"\n  {p}" for p in outside))
    ok = all(min(totals[n]) >= Q41_POINTS - 1e-9 for n in correct) and all(
        max(totals[n]) <= Q41_POINTS / 2 for n in wrong) and not outside
    lines.append("every correct matcher keeps 15/15 and both wrong ones at most 7.5/15: " + ("yes" if ok else "NO"))
    return "\n".join(lines), ok


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--secrets", type=int, default=20, help="how many of the sweep's secrets (default 20)")
    ap.add_argument("--jobs", type=int, default=2, help="processes (default 2)")
    args = ap.parse_args(argv)
    secrets = [f"sweep-secret-{k:02d}" for k in range(args.secrets)]
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        rows = list(pool.map(graded, secrets))
    table, ok = report(rows)
    print(table)
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
