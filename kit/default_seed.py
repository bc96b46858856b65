"""Which temple seed makes the default data: the figures a seed gives, and the criterion it must meet.

    python -m kit.default_seed [--start 0] [--stop 200] [--all]

The default data is meant to behave like the official data (docs/data.md), but the figures of
the linear eight-point estimate are a lottery on the rounding of the stored points: leaving one
official point out moves its reprojection error of 89 anywhere from 36 to 1073, and temple seeds
0 to 74 give 94 to 11600.  So the seed is chosen, by the criterion below, as the first seed from 0
upward whose scene meets it;
scenes.defaults.TEMPLE_SEED records the result and tests/scenes_tests/test_generated_scenes.py checks that
the default scene meets the criterion.  The command scans seeds and prints each one's figures,
stopping at the first that meets it (``--all``: scans the whole range).

The figures are those of ``python -m kit run`` (same calls, same RANSAC seed), computed on the
scene's arrays rather than on files; the official ones are in docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

__all__ = ["CRITERION", "OFFICIAL", "figures", "unmet", "main"]

# The official data's figures (python -m kit run --data ../shared/course-data; docs/benchmarks.md).
OFFICIAL = {"without refineF": 89.44, "with refineF": 352.0, "transposed F": 1927.0,
            "RANSAC inliers at 1 px": (105, 108), "after bundle adjustment": 8.0}

# What a default seed must give, and why (each bound is the official figure's neighbourhood or a
# limit of tests/scenes_tests/test_generated_scenes.py):
CRITERION = {
    # within a factor of 2 of the official 89.44 (the handout: "about 89")
    "without refineF": (89.44 / 2, 89.44 * 2),
    # a transposed F clearly worse (the FAQ's warning sign; official 1927 / 89.44 = 21.5)
    "transposed F / without refineF": (10.0, np.inf),
    # the handout's "about 100" at 1 px; the 110 true matches plus the outliers slid along their
    # epipolar line (15) are the most an epipolar test can keep
    "RANSAC inliers at 1 px": (100, 125),
    # bundle adjustment from the RANSAC inliers to about 10 (official 8.0; 10.885 from the clean pairs)
    "after bundle adjustment": (8.0, 12.0),
    # the limits of tests/scenes_tests/test_generated_scenes.py against the ground truth
    "eight-point median epipolar distance (px)": (0.0, 1.0),
    "eight-point 90th percentile epipolar distance (px)": (0.0, 2.5),
    "bundle adjustment median shape error (%)": (0.0, 3.0),
}


def figures(scene) -> dict:
    """The criterion's figures of a TempleScene (names as in CRITERION, plus a few for the record)."""
    from core.geometry import IDENTITY_POSE as M1
    from solutions import bundleAdjustment, eightpoint, findM2, triangulate
    from starter import epipolar_distances, ransacF

    s, out = scene, {}
    C1 = s.K1 @ M1

    def reprojection(F):
        M2, C2, w = findM2(F, s.pts1, s.pts2, s.K1, s.K2)
        return float(triangulate(C1, s.pts1, C2, s.pts2)[1])

    F_plain = eightpoint(s.pts1, s.pts2, s.M, refine=False)
    F_refined = eightpoint(s.pts1, s.pts2, s.M)
    out["without refineF"] = reprojection(F_plain)
    out["with refineF"] = reprojection(F_refined)
    out["transposed F"] = reprojection(F_plain.T)
    out["transposed F / without refineF"] = out["transposed F"] / out["without refineF"]
    d = [epipolar_distances(F, s.pts1_true, s.pts2_true) for F in (F_plain, F_refined)]
    out["eight-point median epipolar distance (px)"] = float(max(np.median(x) for x in d))
    out["eight-point 90th percentile epipolar distance (px)"] = float(max(np.percentile(x, 90) for x in d))

    # As kit.pipeline: RANSAC at 1 px seeded 0, bundle adjustment from its inliers.
    F_r, inl = ransacF(s.pts1_noisy, s.pts2_noisy, s.M, eightpoint, tol=1.0, rng=np.random.default_rng(0))
    out["RANSAC inliers at 1 px"] = int(inl.sum())
    p1, p2 = s.pts1_noisy[inl], s.pts2_noisy[inl]
    M2_r, _, w_r = findM2(F_r, p1, p2, s.K1, s.K2)
    M2_ba, w_ba, o1, o2 = bundleAdjustment(s.K1, M1, p1, s.K2, M2_r, p2, w_r)
    out["before bundle adjustment"], out["after bundle adjustment"] = float(o1), float(o2)
    # As tests/scenes_tests/test_generated_scenes.py: the kept true matches against their 3D points, at the true scale.
    good = inl & s.inlier_mask
    X_true = s.X[s.noisy_source[good]]
    est = w_ba[good[inl]] * np.linalg.norm(s.M2[:, 3])
    rel = np.linalg.norm(est - X_true, axis=1) / np.linalg.norm(X_true, axis=1)
    out["bundle adjustment median shape error (%)"] = float(100 * np.median(rel))
    return out


def unmet(figs: dict) -> list[str]:
    """The criterion's lines a seed's figures do not meet (an empty list: the seed qualifies)."""
    return [f"{name} {figs[name]:.4g} outside [{lo:g}, {hi:g}]"
            for name, (lo, hi) in CRITERION.items() if not lo <= figs[name] <= hi]


def main(argv=None) -> int:
    from scenes.envelope import outside_envelope
    from scenes.temple import make_temple_scene

    p = argparse.ArgumentParser(prog="python -m kit.default_seed", description=__doc__.split("\n\n")[0])
    p.add_argument("--start", type=int, default=0)
    p.add_argument("--stop", type=int, default=200, help="first seed not scanned")
    p.add_argument("--all", action="store_true", help="scan the whole range, not only to the first seed that qualifies")
    args = p.parse_args(argv)
    keys = ("without refineF", "with refineF", "transposed F", "RANSAC inliers at 1 px", "before bundle adjustment",
            "after bundle adjustment", "eight-point median epipolar distance (px)",
            "bundle adjustment median shape error (%)")
    print("seed " + " | ".join(keys))
    found = None
    for seed in range(args.start, args.stop):
        t0 = time.perf_counter()
        scene = make_temple_scene(seed)
        figs = figures(scene)
        missing = unmet(figs) + outside_envelope(scene, noise_px=0.2)
        print(f"{seed:4d} " + " | ".join(f"{figs[k]:.4g}" for k in keys)
              + f"  ({time.perf_counter() - t0:.1f} s) " + ("QUALIFIES" if not missing else "; ".join(missing)),
              flush=True)
        if not missing and found is None:
            found = seed
            if not args.all:
                break
    print(f"first seed meeting the criterion: {found}" if found is not None else "no seed in the range meets it")
    return 0 if found is not None else 1


if __name__ == "__main__":
    sys.exit(main())
