"""Where Q5's full-marks goal sits (``judging.bundle.OPTIMUM_SLACK``), measured on the hidden problems.

For each secret of the sweep (``tests/end_to_end/test_secret_sweep.py``'s names) the hidden bundle-adjustment
problems are built as the grader builds them, and four bundle adjustments written as students
write them run on each; the table gives each one's final error as a multiple of the problem's
optimum, beside the goal's multiple:

- converged: ``scipy.optimize.minimize`` on the summed squares with its defaults (the baseline);
- capped: the same capped at 500 iterations (a habit of real hand-ins: it stops early);
- points only / camera only: ``least_squares`` over one block, the other left at the start.

A goal is right when every capped run is under it and every one-block run above it.

    python benchmarks/bundle_goal.py [--secrets 20]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import scipy.optimize

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/core.py must not hide core/

from autograder.inputs.config import quick_config  # noqa: E402
from autograder.inputs.build import build_hidden_inputs  # noqa: E402
from core.geometry import IDENTITY_POSE  # noqa: E402
from judging.bundle import OPTIMUM_SLACK, total_error  # noqa: E402
from solutions import rodriguesResidual  # noqa: E402
from starter import invRodrigues, rodrigues  # noqa: E402

STYLES = ("converged", "capped", "points only", "camera only")


def final_error(problem, style: str) -> float:
    """The total squared reprojection error (pixels^2) a bundle adjustment of ``style`` ends at."""
    K1, K2, p1, p2 = problem.K1, problem.K2, problem.p1, problem.p2
    n = len(p1)
    x0 = np.concatenate([problem.w_init.ravel(), invRodrigues(problem.M2_init[:, :3]).ravel(), problem.M2_init[:, 3]])

    def res(x):
        return rodriguesResidual(K1, IDENTITY_POSE, p1, K2, p2, x)

    if style == "converged":
        x = scipy.optimize.minimize(lambda x: np.sum(res(x) ** 2), x0).x
    elif style == "capped":
        x = scipy.optimize.minimize(lambda x: np.sum(res(x) ** 2), x0, method="L-BFGS-B",
                                    options={"maxiter": 500}).x
    elif style == "points only":
        z = scipy.optimize.least_squares(lambda z: res(np.concatenate([z, x0[3 * n:]])), x0[:3 * n]).x
        x = np.concatenate([z, x0[3 * n:]])
    else:
        z = scipy.optimize.least_squares(lambda z: res(np.concatenate([x0[:3 * n], z])), x0[3 * n:]).x
        x = np.concatenate([x0[:3 * n], z])
    M2 = np.hstack([rodrigues(x[3 * n:3 * n + 3]), x[3 * n + 3:, None]])
    return total_error(K1, K2, p1, p2, M2, x[:3 * n].reshape(n, 3))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--secrets", type=int, default=20)
    args = parser.parse_args()
    print(f"{'secret':>6} {'problem':<16}" + "".join(f"{s:>13}" for s in STYLES))
    ratios = {s: [] for s in STYLES}
    for k in range(args.secrets):
        hidden = build_hidden_inputs(quick_config(secret=f"sweep-secret-{k:02d}"))
        for problem in hidden.prepared["bundle"].problems:
            row = {s: final_error(problem, s) / problem.optimum for s in STYLES}
            for s in STYLES:
                ratios[s].append(row[s])
            print(f"{k:>6} {problem.label:<16}" + "".join(f"{row[s]:>13.3f}" for s in STYLES), flush=True)
    print(f"\ngoal: {OPTIMUM_SLACK:g} x the optimum (+ 0.05 px^2)")
    print(f"converged (baseline): worst {max(ratios['converged']):.3f} x")
    print(f"capped at 500 iterations: worst {max(ratios['capped']):.3f} x "
          f"({sum(r <= OPTIMUM_SLACK for r in ratios['capped'])} of {len(ratios['capped'])} within the goal)")
    one_block = ratios["points only"] + ratios["camera only"]
    print(f"one block left out: best {min(one_block):.3f} x "
          f"({sum(r > OPTIMUM_SLACK for r in one_block)} of {len(one_block)} above the goal)")


if __name__ == "__main__":
    main()
