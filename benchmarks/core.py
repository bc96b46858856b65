"""Time each reference step beside its OpenCV equivalent, in the same run, and print the ratios.

    python benchmarks/core.py [--data DIR] [--repeat 20] [--no-minimize]

Data: the official course data when ../shared/course-data exists (or --data), else the kit's
data/.  Each figure is the median of --repeat runs.  OpenCV (opencv-python-headless) is a
benchmark-only dependency: it is in requirements-dev.txt, not requirements.txt.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

# One thread for every library, ours and OpenCV's alike: on a small machine a multi-threaded BLAS
# spinning on 3x3 SVDs costs more than it saves and makes the timings noisy.
for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from anywhere without installing
from core.paths import course_data_dir  # noqa: E402


def median_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=None)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--no-minimize", action="store_true", help="skip the slow scipy.optimize.minimize baseline")
    args = ap.parse_args(argv)

    import cv2
    import scipy.optimize

    cv2.setNumThreads(1)

    from solutions import bundleAdjustment, compute3D_pts, eightpoint, epipolarCorrespondence, findM2, triangulate
    from solutions.bundle import rodriguesResidual
    from starter import invRodrigues, load_temple, ransacF

    official = course_data_dir()
    data = args.data or (official if official is not None and (official / "temple").is_dir() else None)
    d = load_temple(data)
    print(f"data: {d.folder}; numpy {np.__version__}, OpenCV {cv2.__version__}; median of {args.repeat} runs")
    M1 = np.hstack([np.eye(3), np.zeros((3, 1))])
    C1 = d.K1 @ M1
    r = args.repeat
    rows = []

    t_ours = median_time(lambda: eightpoint(d.pts1, d.pts2, d.M, refine=False), r)
    t_cv = median_time(lambda: cv2.findFundamentalMat(d.pts1, d.pts2, cv2.FM_8POINT), r)
    rows.append(("eightpoint (no refineF) vs FM_8POINT", t_ours, t_cv))
    rows.append(("eightpoint + refineF vs FM_8POINT", median_time(lambda: eightpoint(d.pts1, d.pts2, d.M), max(3, r // 4)), t_cv))

    t_ours = median_time(lambda: ransacF(d.noisy_pts1, d.noisy_pts2, d.M, eightpoint, tol=1.0,
                                         rng=np.random.default_rng(0)), r)
    t_cv = median_time(lambda: cv2.findFundamentalMat(d.noisy_pts1, d.noisy_pts2, cv2.FM_RANSAC, 1.0, 0.99), r)
    rows.append(("ransacF (1 px, adaptive) vs FM_RANSAC", t_ours, t_cv))

    F = eightpoint(d.pts1, d.pts2, d.M, refine=False)
    M2, C2, w = findM2(F, d.pts1, d.pts2, d.K1, d.K2)
    t_ours = median_time(lambda: triangulate(C1, d.pts1, C2, d.pts2), r)
    t_cv = median_time(lambda: cv2.triangulatePoints(C1, C2, d.pts1.T, d.pts2.T), r)
    rows.append(("triangulate vs triangulatePoints", t_ours, t_cv))

    t_match = median_time(lambda: [epipolarCorrespondence(d.im1, d.im2, F, x, y) for x, y in zip(d.x1, d.y1)],
                          max(3, r // 4))
    t_ba = median_time(lambda: bundleAdjustment(d.K1, M1, d.pts1, d.K2, M2, d.pts2, w), max(3, r // 4))

    print(f"\n{'step':<44}{'ours (ms)':>12}{'OpenCV (ms)':>14}{'ratio':>9}")
    for name, ours, cv in rows:
        print(f"{name:<44}{ours * 1e3:>12.3f}{cv * 1e3:>14.3f}{ours / cv:>9.1f}")
    print(f"{'epipolarCorrespondence, all templeCoords':<44}{t_match * 1e3:>12.1f}{'-':>14}{'-':>9}")
    print(f"{'bundleAdjustment, 110 clean pairs':<44}{t_ba * 1e3:>12.1f}{'-':>14}{'-':>9}")

    if not args.no_minimize:
        # The handout's route: minimize on the summed squares (BFGS, numerical gradient), once.
        n = len(w)
        x0 = np.concatenate([w.ravel(), invRodrigues(M2[:, :3]), M2[:, 3]])
        t0 = time.perf_counter()
        res = scipy.optimize.minimize(lambda x: np.sum(rodriguesResidual(d.K1, M1, d.pts1, d.K2, d.pts2, x) ** 2), x0)
        t_min = time.perf_counter() - t0
        o2 = bundleAdjustment(d.K1, M1, d.pts1, d.K2, M2, d.pts2, w)[3]
        print(f"\nbundle adjustment: least_squares {t_ba:.3f} s to {o2:.3f}; handout's minimize (BFGS) "
              f"{t_min:.1f} s to {res.fun:.3f} (success={res.success}, {res.nfev} evaluations); "
              f"speed-up {t_min / t_ba:.0f}x for N = {n}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
