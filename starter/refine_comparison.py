"""Q3.2's printed figures: the reprojection error of the student's F with refineF and without.

Problem 3 asks for the total reprojection error of the 110 matches twice, as the FAQ does: with
``eightpoint`` as written, and with refineF switched off ("comment out the call to refineF").
:func:`reprojection_errors` runs the student's ``eightpoint``, ``findM2`` and ``triangulate``
both ways (the switch is ``core.refine_switch``, the one the self-check and the grader throw),
prints one line per way and draws how the error spreads over the matches.  Each of the
student's functions runs through :func:`starter.notebook_import.try_run`, so a crash prints one
line naming the function and the notebook goes on.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field

import numpy as np

from core.geometry import project
from core.refine_switch import switched_off

from .notebook_import import try_run

__all__ = ["RefineComparison", "reprojection_errors"]

AS_WRITTEN = "as written"
SWITCHED_OFF = "refineF switched off"


@dataclass
class RefineComparison:
    """What :func:`reprojection_errors` found: ``errors`` maps "as written" / "refineF switched off"
    to the total squared reprojection error (px^2) of that F, for the ways that ran through;
    ``calls_refineF`` is False when eightpoint never called refineF (both ways then agree)."""

    errors: dict[str, float] = field(default_factory=dict)
    calls_refineF: bool = True


def _switched_off_run(eightpoint):
    def eightpoint_without_refineF(pts1, pts2, M):
        with switched_off(eightpoint) as run:
            F = eightpoint(pts1, pts2, M)
        return F, run.calls

    return eightpoint_without_refineF


def _histogram_png(distances: np.ndarray) -> bytes:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 3))
    ax = fig.subplots()
    ax.hist(distances, bins=30)
    ax.set_xlabel("reprojection distance per match (px, both images)")
    ax.set_ylabel("matches")
    ax.set_title("Q3.2 reprojection error of the best F")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    return buf.getvalue()


def reprojection_errors(eightpoint, findM2, triangulate, data, *, show: bool = True) -> RefineComparison:
    """Print the total reprojection error of the student's F both ways, and draw its spread.

    Parameters
    ----------
    eightpoint, findM2, triangulate : the student's functions (handout signatures).
    data : the temple (``starter.load_temple()``): pts1, pts2 (N, 2), M, K1, K2.
    show : display the histogram (in a notebook) of the best F's per-match distances.

    Returns
    -------
    RefineComparison
        A way whose function failed or is a stub is missing from ``errors`` (its one-line note
        was printed).
    """
    result = RefineComparison()
    C1 = data.K1 @ np.hstack([np.eye(3), np.zeros((3, 1))])
    F = try_run(eightpoint, data.pts1, data.pts2, data.M)
    plain = try_run(_switched_off_run(eightpoint), data.pts1, data.pts2, data.M)
    if plain is not None and not plain[1]:
        result.calls_refineF = False
        print("your eightpoint does not call refineF: both rows use the same F")
    best = None
    for label, F_r in ((AS_WRITTEN, F), (SWITCHED_OFF, None if plain is None else plain[0])):
        found = None if F_r is None else try_run(findM2, F_r, data.pts1, data.pts2, data.K1, data.K2)
        if found is None:
            continue
        C2 = found[1]
        tri = try_run(triangulate, C1, data.pts1, C2, data.pts2)
        if tri is None:
            continue
        w, err = np.asarray(tri[0], float), float(tri[1])
        if w.ndim == 2 and w.shape[1] == 4:  # homogeneous points
            w = w[:, :3] / w[:, 3:]
        result.errors[label] = err
        print(f"eightpoint {label:21}: total reprojection error {err:10.2f}, {err / len(w):.2f} per match")
        if best is None or err < best[0]:
            best = (err, C2, w)
    if best is not None and show:
        _, C2, w = best
        try:
            per_match = sum(np.sum((pts - project(C, w)) ** 2, axis=1)
                            for C, pts in ((C1, data.pts1), (np.asarray(C2, float), data.pts2)))
        except ValueError as exc:
            print(f"the histogram is skipped: {exc}")
            return result
        from IPython.display import Image, display

        display(Image(data=_histogram_png(np.sqrt(per_match))))
    return result
