"""Q5's figure: bundle adjustment before and after, with the history of the objective.

Student side (:func:`run`): ``bundleAdjustment(K1, M1, p1, K2, M2_init, p2, w_init) -> (M2, w, o1,
o2)`` on the public problem (q5_problem), the sums of squares of every residual vector its code
got from ``rodriguesResidual`` recorded (q5_problem.recording); and ``rodriguesResidual(K1, M1,
p1, K2, p2, x)`` at the start x = [w_init.ravel(), r2, t2] when given.

Trusted side (:func:`draw`): the objective call by call, beside it two bars, |t| at the start and
as returned (points and t shrunk together reproject as well as the right ones: the vanishing bar
shows a scale collapse that the images cannot); image 2 with the observed points and
their reprojections before and after; and the student's residuals at the
start against the handout's layout [(p1 - p1_hat).ravel(), (p2 - p2_hat).ravel()] (those of the
handout precomputed on the grader's side, see .precomputed: the residual cannot ship).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from core.geometry import project

from . import precomputed
from .arrays import call, count, maybe, need, number, read, said
from .drawing import image, two_bars
from .picture import Picture, figure, measure_text, to_picture
from .public import need_truth, temple
from .q5_problem import problem, recording, start_x

__all__ = ["FUNCTIONS", "draw", "run"]

FUNCTIONS = ("bundleAdjustment", "rodriguesResidual")


def run(functions: Mapping[str, Callable], root=None) -> dict[str, np.ndarray]:
    """{"M2": (3, 4), "w": (N, 3), "o1": (1,), "o2": (1,) (NaN when not one number), "o1_size", "o2_size":
    (1,) how many numbers each holds (1 for a number), "history": (K,) the objective recorded call by
    call (the calls of rodriguesResidual; when there are none, the objective scipy.optimize was given;
    K may be 0), "history_source": (1,) 0 for rodriguesResidual, 1 for the optimiser's objective,
    "residuals_start": (4N,) when rodriguesResidual is given}."""
    from judging.bundle import read_ba, read_residuals

    pub = temple(root)
    pr = problem(need_truth(pub, "Q5"), pub.data)
    out = {}
    rr = functions.get("rodriguesResidual")
    if callable(rr):
        r = call(rr, "rodriguesResidual", pr.K1.copy(), pr.M1.copy(), pr.p1.copy(), pr.K2.copy(), pr.p2.copy(), start_x(pr))
        out["residuals_start"] = np.asarray(read(read_residuals, r, len(pr.p1), name="rodriguesResidual"), float)
    ba = functions["bundleAdjustment"]
    with recording(ba) as recorded:
        value = call(ba, "bundleAdjustment", pr.K1.copy(), pr.M1.copy(), pr.p1.copy(), pr.K2.copy(),
                     pr.M2_init.copy(), pr.p2.copy(), pr.w_init.copy())
    M2, w, o1, o2 = read(read_ba, value, len(pr.p1), name="bundleAdjustment")
    source = 0 if recorded["residual"] else 1
    history = recorded["residual"] or recorded["optimiser"]
    out.update({"M2": np.asarray(M2, float), "w": np.asarray(w, float), "o1": number(o1, "o1"),
                "o2": number(o2, "o2"), "o1_size": count(o1), "o2_size": count(o2),
                "history": np.asarray(history, float).reshape(-1),
                "history_source": np.array([float(source)])})
    return out


def _offsets(ax, p, q, colour, gid):
    for (x0, y0), (x1, y1) in zip(p, q):
        if np.all(np.isfinite([x1, y1])):
            ax.plot([x0, x1], [y0, y1], color=colour, lw=1.0, gid=gid)


def _scale_bars(ax, t_start: float, t_end: float) -> None:
    """Two bars on the right of ``ax`` (the objective's panel, empty there once the objective has
    fallen): |t| at the start (grey) and returned (orange), on one linear scale.  Points and t shrunk together reproject as well as the right ones, so the
    images cannot show a scale collapse; the orange bar's vanishing does."""
    two_bars(ax, (0.76, 0.3, 0.2, 0.38), [t_start, t_end], ["#9e9e9e", "#ffb300"], ["start", "yours"],
             "|t|", "scale_bars")


def draw(outputs: Mapping[str, np.ndarray], root=None) -> Picture:
    """The Picture of Q5.

    measures: start_error, end_error (total squared reprojection error, pixels^2, recomputed from
    the start and from the M2, w returned), o1_reported, o2_reported, n_calls (residual vectors
    recorded), history_first, history_min (the first and the lowest recorded objective; NaN when none),
    t_ratio (|t| returned / |t| at the start), residual_layout_gap (largest difference of the
    student's residuals at the start from the handout's, over the largest of these, up to sign;
    present when rodriguesResidual was run).  ValueError when rodriguesResidual was run and the
    handout's residuals of the problem were not precomputed (data other than the default).
    """
    from judging.bundle import total_error

    pub = temple(root)
    pr = problem(need_truth(pub, "Q5"), pub.data)
    n = len(pr.p1)
    M2, w = need(outputs, "M2", (3, 4)), need(outputs, "w", (n, 3))
    o1, o2 = float(need(outputs, "o1", (1,))[0]), float(need(outputs, "o2", (1,))[0])
    sizes = [None if maybe(outputs, k, (1,)) is None else float(outputs[k][0]) for k in ("o1_size", "o2_size")]
    history = need(outputs, "history", (None,))
    from_residual = float(need(outputs, "history_source", (1,))[0]) == 0
    source = "rodriguesResidual" if from_residual else "the optimiser's objective"
    res = maybe(outputs, "residuals_start", (4 * n,))
    e = None if res is None else precomputed.start_residuals(pr.p1, pr.p2, pr.K1, pr.K2)
    if res is not None and e is None:
        raise ValueError(f"Q5's figure: the handout's residuals at the start are {precomputed.NOT_PRECOMPUTED} "
                         "(restore data/ with `python -m kit data`, or write them with `python -m kit check-data`)")
    start = total_error(pr.K1, pr.K2, pr.p1, pr.p2, pr.M2_init, pr.w_init)
    end = total_error(pr.K1, pr.K2, pr.p1, pr.p2, M2, w)
    m = {"start_error": start, "end_error": end, "o1_reported": o1, "o2_reported": o2,
         "n_calls": float(len(history)),
         "history_first": float(history[0]) if len(history) else float("nan"),
         "history_min": float(np.nanmin(history)) if np.any(np.isfinite(history)) else float("nan"),
         "t_ratio": float(np.linalg.norm(M2[:, 3]) / np.linalg.norm(pr.M2_init[:, 3]))}
    fig, axes = figure(3 if res is not None else 2, size=(4.6, 3.8))
    ax = axes[0]
    if len(history):
        k = np.arange(1, len(history) + 1)
        ax.plot(k, history, ".", ms=2, color="#ffcc80", gid="history")
        best = np.fmin.accumulate(np.where(np.isfinite(history), history, np.inf))
        ax.plot(k, best, "-", lw=1.2, color="#ff6f00", gid="history_best")
    ax.axhline(start, color="#888", ls="--", lw=0.8, gid="start_error")
    ax.axhline(end if np.isfinite(end) else start, color="#2e7d32", ls=":", lw=1.0, gid="end_error")
    finite = history[np.isfinite(history) & (history > 0)]
    if len(finite) and finite.max() / max(finite.min(), 1e-300) > 20:
        ax.set_yscale("log")
    ax.set_title(f"{source}, call by call (px^2)" if len(history) else "no objective evaluation recorded",
                 fontsize=8)
    ax.set_xlabel(f"calls; start {measure_text(start)} (dashed), returned M2 and w {measure_text(end)} (dotted),\n"
                  "dots: each call, line: lowest so far", fontsize=7)
    _scale_bars(ax, np.linalg.norm(pr.M2_init[:, 3]), np.linalg.norm(M2[:, 3]))
    ax = axes[1]
    # one line: a second ran into the figure's title; the bars beside the objective show the scale
    image(ax, pub.data.im2, f"image 2: reprojections before and after; |t| of M2 x{m['t_ratio']:.3g}"
          + ("" if 0.5 <= m["t_ratio"] <= 2 else (", w and t shrunk" if m["t_ratio"] < 0.5 else ", w and t grown")))
    C2a, C2b = pr.K2 @ pr.M2_init, pr.K2 @ M2
    with np.errstate(all="ignore"):
        _offsets(ax, pr.p2, project(C2a, pr.w_init), "#9e9e9e", "before")
        _offsets(ax, pr.p2, project(C2b, w), "#ffb300", "after")
    ax.plot(pr.p2[:, 0], pr.p2[:, 1], "o", ms=3, mfc="#e53935", mec="white", mew=0.5, gid="observed")
    lo, hi = pr.p2.min(axis=0) - 40, pr.p2.max(axis=0) + 40
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(hi[1], lo[1])
    ax.set_xlabel("segments from each observed point (dot) to its reprojection:\ngrey before, orange after "
                  "(too short to see: within a pixel)", fontsize=7)
    if res is not None:
        scale = max(float(np.abs(e).max()), 1e-12)
        m["residual_layout_gap"] = float(min(np.abs(res - e).max(), np.abs(res + e).max()) / scale)
        ax = axes[2]
        ax.plot(e, "-", lw=0.8, color="#4fc3f7", gid="handout_residuals", label="the handout's layout")
        ax.plot(res, ".", ms=2.5, color="#ffb300", gid="student_residuals", label="yours")
        ax.axvline(2 * n - 0.5, color="#888", lw=0.5)
        ax.set_title("rodriguesResidual at the start (px)", fontsize=8)
        ax.set_xlabel(f"index (image 1 | image 2); largest gap {m['residual_layout_gap']:.3g} of the largest residual",
                      fontsize=7)
        ax.legend(fontsize=7)
    drop = "lower" if end < start * (1 - 1e-6) else "not lower"
    alt = (f"Bundle adjustment of {n} points from a start moved away from the truth: the total squared reprojection "
           f"error goes from {measure_text(start, 'px^2')} to {measure_text(end, 'px^2')} with the M2 and w returned ({drop}); you "
           f"reported {said('o1', o1, sizes[0])} and {said('o2', o2, sizes[1])}; |t| changed by a factor "
           f"{m['t_ratio']:.3g} (two bars beside the objective: |t| at the start and returned). "
           + (f"The objective was evaluated {len(history)} times, from {measure_text(m['history_first'])} to "
              f"a lowest value of {measure_text(m['history_min'])} ({source})." if len(history) else "No evaluation of the "
              "objective was recorded (neither rodriguesResidual nor a scipy.optimize objective).")
           + (f" Your residuals at the start differ from the handout's layout by {m['residual_layout_gap']:.3g} of "
              "the largest residual." if res is not None else ""))
    return to_picture("Q5", "bundleAdjustment: before and after", fig, alt, m)
