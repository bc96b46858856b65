"""The kit's main job: the whole homework pipeline run with the reference solutions on one data folder.

It prints the figures a student compares against (reprojection errors, RANSAC inliers, bundle
adjustment before/after, the car's error per threshold) and writes the homework's figures as
PNG files.  ``python -m kit run`` calls :func:`run`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["Report", "run"]

M1 = np.hstack([np.eye(3), np.zeros((3, 1))])


@dataclass
class Report:
    """What the pipeline measured: ``figures`` name -> number, ``files`` written, ``seconds`` per step."""

    figures: dict = field(default_factory=dict)
    files: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)

    def lines(self) -> list[str]:
        rows = [f"  {name:<48} {value:>12.4g}" if isinstance(value, float) else f"  {name:<48} {value:>12}"
                for name, value in self.figures.items()]
        rows.append("  time per step (s): " + ", ".join(f"{k} {v:.2f}" for k, v in self.seconds.items()))
        return rows


class _Timer:
    def __init__(self, report: Report, name: str):
        self.report, self.name = report, name

    def __enter__(self):
        self.t0 = time.perf_counter()

    def __exit__(self, *exc):
        self.report.seconds[self.name] = time.perf_counter() - self.t0


def run(data: str | Path | None = None, out: str | Path = "out", *, thresholds=(300, 500, 700), seed: int = 0,
        tol: float = 1.0, figures: bool = True, echo=print) -> Report:
    """Run problems 2 to 6 on the data folder ``data`` (default: the kit's data/) and write figures to ``out``.

    thresholds: the confidence thresholds of the problem-6 study; the middle one draws the car.
    seed: seeds the RANSAC Generator.  tol: RANSAC inlier threshold in pixels.
    """
    from solutions import (MultiviewReconstruction, bundleAdjustment, compute3D_pts, eightpoint, findM2,
                           triangulate)
    from starter import car_times, load_car_frame, load_temple, ransacF

    rep = Report()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with _Timer(rep, "load"):
        d = load_temple(data)
    echo(f"temple data: {d.folder} ({d.im1.shape[1]}x{d.im1.shape[0]}, {len(d.pts1)} matches, "
         f"{len(d.noisy_pts1)} noisy matches, {len(d.x1)} temple points)")
    C1 = d.K1 @ M1

    with _Timer(rep, "Q2-Q3"):
        F_plain = eightpoint(d.pts1, d.pts2, d.M, refine=False)
        F = eightpoint(d.pts1, d.pts2, d.M)
        for name, f in (("without refineF", F_plain), ("with refineF", F)):
            M2, C2, w = findM2(f, d.pts1, d.pts2, d.K1, d.K2)
            rep.figures[f"Q3.2 reprojection error, {name}"] = triangulate(C1, d.pts1, C2, d.pts2)[1]
    M2, C2, w = findM2(F_plain, d.pts1, d.pts2, d.K1, d.K2)

    with _Timer(rep, "Q4"):
        W, pts2 = compute3D_pts(d.im1, d.im2, F_plain, d.x1, d.y1, C1, C2)
        lo, hi = np.percentile(w[:, 2], [0, 100])
        rep.figures["Q4.2 temple points at a plausible depth"] = \
            f"{int(np.sum((W[:, 2] > 0.9 * lo) & (W[:, 2] < 1.1 * hi)))}/{len(W)}"

    with _Timer(rep, "Q5"):
        F_r, inl = ransacF(d.noisy_pts1, d.noisy_pts2, d.M, eightpoint, tol=tol, rng=np.random.default_rng(seed))
        rep.figures[f"Q5 RANSAC inliers at {tol:g} px"] = f"{int(inl.sum())}/{len(inl)}"
        p1, p2 = d.noisy_pts1[inl], d.noisy_pts2[inl]
        M2_r, _, w_r = findM2(F_r, p1, p2, d.K1, d.K2)
        M2_ba, w_ba, o1, o2 = bundleAdjustment(d.K1, M1, p1, d.K2, M2_r, p2, w_r)
        rep.figures["Q5 reprojection error before bundle adjustment"] = o1
        rep.figures["Q5 reprojection error after bundle adjustment"] = o2

    car = None
    try:
        times = car_times(data)
    except FileNotFoundError as exc:
        echo(f"problem 6 skipped: {exc}")
        times = []
    if times:
        with _Timer(rep, "Q6"):
            frames = [load_car_frame(t, data, images=False) for t in times]
            for th in thresholds:
                results = [MultiviewReconstruction(f.C[0], f.pts[0], f.C[1], f.pts[1], f.C[2], f.pts[2], th)
                           for f in frames]
                rep.figures[f"Q6 mean error per frame, Thres {th}"] = float(np.mean([r[1] for r in results]))
                rep.figures[f"Q6 keypoints reconstructed, Thres {th}"] = \
                    f"{sum(int(np.isfinite(r[0][:, 0]).sum()) for r in results)}/{12 * len(results)}"
                if th == thresholds[len(thresholds) // 2]:
                    car = (th, np.stack([r[0] for r in results]))

    if figures:
        with _Timer(rep, "figures"):
            rep.files += _write_figures(out, d, F_plain, W, w_r, w_ba, o1, o2, car, data, times)
    echo("figures:")
    for line in rep.lines():
        echo(line)
    for f in rep.files:
        echo(f"wrote {f}")
    return rep


def _write_figures(out, d, F, W, w_before, w_after, o1, o2, car, data, times) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from starter import load_car_frame
    from starter.figures import plot_points_3d
    from solutions import epipolarCorrespondence
    from starter.interactive import EpipolarSession
    from starter.keypoints import plot_3d_keypoint_frames, visualize_keypoints

    files = []

    def save(fig, name):
        path = out / name
        fig.savefig(path, dpi=100)
        files.append(path)
        plt.close(fig) if isinstance(fig, plt.Figure) else None

    def pairs(points, match_fn=None):
        session = EpipolarSession(d.im1, d.im2, F, match_fn)
        for x, y in points:
            session.pick(x, y)
        return session.figure()

    # Q2: six point-line pairs spread over the object; Q4.1: the same with the matches found.
    idx = np.linspace(0, len(d.pts1) - 1, 6).astype(int)
    save(pairs(d.pts1[idx]), "q2_epipolar_lines.png")
    jdx = np.linspace(0, len(d.x1) - 1, 6).astype(int)
    save(pairs(np.column_stack([d.x1, d.y1])[jdx], epipolarCorrespondence), "q4_epipolar_matches.png")
    save(plot_points_3d(W, title=f"Q4.2 the temple from {len(W)} matched points\n"
                                 "(camera-1 frame, unit: the baseline |t2| = 1)").matplotlib, "q4_temple_3d.png")
    save(plot_points_3d([w_before, w_after], labels=[f"before BA ({o1:.1f})", f"after BA ({o2:.1f})"],
                        title="Q5 bundle adjustment", layout="side_by_side").matplotlib, "q5_bundle_adjustment.png")
    if car is not None:
        th, video = car
        frame = load_car_frame(times[0], data)
        fig, axes = plt.subplots(1, 3, figsize=(15, 3.2))
        for i, ax in enumerate(axes):
            visualize_keypoints(frame.images[i], frame.pts[i], th, ax=ax)
            ax.set_title(f"camera {i + 1}, time {times[0]}")
        save(fig, "q6_keypoints.png")
        save(plot_3d_keypoint_frames(video, title=f"Q6 the car over {len(video)} frames (Thres {th})").matplotlib,
             "q6_car_video.png")
    return files
