"""Q3.1's figure: the epipolar lines that the student's E implies, in image 2, through the true matches.

Student side (:func:`run`): ``essentialMatrix(F, K1, K2) -> E`` (3, 3), given a true F as the
self-check does, twice: on the public temple data (its true F and intrinsics; there K1 == K2), and
on the self-check's generated pair, whose intrinsics differ (K1 != K2, 640 x 480, no image).

Trusted side (:func:`draw`): E is turned back into the F it implies, F_E = K2^-T E K1^-1 (3, 3,
mapping a point x1 of image 1, pixels (x, y), to its line F_E x1 in image 2), and drawn as Q2's
figure draws an F (q2_eightpoint.lines_row): image 2 with the lines of eight matches (solid), the
true F's lines (dashed) and the true matches (dots), from every true match a red stick towards its
line, MISS_MAGNIFY times its distance, and zooms on the matches farthest from their lines.  A right
E's lines pass through the dots and its sticks vanish.  A K missing or inverted misses them by far
(sticks to the image's edge); a transposed E by a few pixels (sticks tens of pixels long, the line
beside the dot in the zooms).  K1 and K2 swapped, or one camera's K used on both sides, give exactly the
right E when K1 == K2, as on the temple: only the second row (K1 != K2) shows them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from .arrays import call, matrix3, maybe, need
from .drawing import clip_line, line_distances
from .picture import Picture, figure, measure_text, to_picture
from .public import need_truth, temple
from .q2_eightpoint import MISS_MAGNIFY, N_DRAWN, N_ZOOMED, ZOOM_PX, drawn_rows, lines_row

__all__ = ["FUNCTIONS", "draw", "implied_F", "run"]

FUNCTIONS = ("essentialMatrix",)
# outputs name -> (panel label, prefix of its measures)
_ROWS = {"E": ("temple (K1 == K2)", ""),
         "E_K_differ": ("check's pair (K1 != K2)", "k_differ_")}


class _Blank:
    """A stand-in for the temple data where there is no image: a mid-grey image 2 of the pair's size."""

    def __init__(self, width: int, height: int):
        self.im2 = np.full((height, width), 128, np.uint8)


def _E(value, what: str) -> np.ndarray:
    return matrix3(value, what, "E")


def run(functions: Mapping[str, Callable], root=None) -> dict[str, np.ndarray]:
    """{"E": (3, 3) on the public temple data's true F, K1, K2; "E_K_differ": (3, 3) on the self-check's
    pair (left out when that call fails)}; PictureRunError when the first call fails."""
    from .._scenes import two_view

    pub = temple(root)
    s, d = need_truth(pub, "Q3.1"), pub.data
    fn = functions["essentialMatrix"]
    out = {"E": _E(call(fn, "essentialMatrix", np.array(s.F_true, float), d.K1.copy(), d.K2.copy()),
                   "essentialMatrix's E")}
    pair = two_view().pair
    try:
        out["E_K_differ"] = _E(call(fn, "essentialMatrix", pair.F.copy(), pair.K1.copy(), pair.K2.copy()),
                               "essentialMatrix's E (K1 != K2)")
    except Exception:  # noqa: BLE001 - the second row only adds to the figure
        pass
    return out


def implied_F(E, K1, K2) -> np.ndarray:
    """The F (3, 3) an E implies: K2^-T E K1^-1 (x2^T F x1 = 0, pixels), the inverse of E = K2^T F K1."""
    return np.linalg.inv(K2).T @ np.asarray(E, float) @ np.linalg.inv(K1)


def _rows(pub):
    """key -> (holder of image 2, K1, K2, true F, true p1 (N, 2), true p2 (N, 2)) of each row; ``pub``
    the public temple with its truth."""
    from .._scenes import two_view

    s, d, pair = need_truth(pub, "Q3.1"), pub.data, two_view().pair
    return {"E": (d, d.K1, d.K2, np.asarray(s.F_true, float), np.asarray(s.pts1_true, float),
                  np.asarray(s.pts2_true, float)),
            "E_K_differ": (_Blank(640, 480), pair.K1, pair.K2, np.asarray(pair.F, float), np.asarray(pair.pts1, float),
                           np.asarray(pair.pts2, float))}


def draw(outputs: Mapping[str, np.ndarray], root=None) -> Picture:
    """The Picture of Q3.1 from run()'s outputs (validated here): one row per E returned.

    measures: mean_distance_px, max_distance_px (the drawn true matches of the temple to the lines
    of F_E), largest_miss_px (of all its true matches, the first zoom), true_F_mean_distance_px, lines_in_image (of F_E crossing image 2), K1_equals_K2 (1 when the temple's K1 == K2:
    swapped or repeated intrinsics cannot show there), and k_differ_mean_distance_px,
    k_differ_max_distance_px, k_differ_largest_miss_px, k_differ_true_F_mean_distance_px, k_differ_lines_in_image for the pair with K1 != K2 when it was run.
    """
    Es = {"E": need(outputs, "E", (3, 3))}
    other = maybe(outputs, "E_K_differ", (3, 3))
    if other is not None:
        Es["E_K_differ"] = other
    pub = temple(root)
    rows = _rows(pub)
    same_k = bool(np.array_equal(pub.data.K1, pub.data.K2))
    fig = figure(size=(11.0, 3.6 * len(Es)))[0]
    fig.clear()
    grid = fig.add_gridspec(2 * len(Es), 5, width_ratios=[3.2, 1, 1, 1, 1])
    measures: dict[str, float] = {"K1_equals_K2": float(same_k), "n_lines": float(N_DRAWN)}
    parts, parts_far = [], []
    for row, (key, E) in enumerate(Es.items()):
        label, prefix = _ROWS[key]
        holder, K1, K2, truth_F, p1, p2 = rows[key]
        with np.errstate(all="ignore"):
            F = implied_F(E, K1, K2)
        picked = drawn_rows(p1, N_DRAWN)
        h1 = np.column_stack([p1[picked], np.ones(len(picked))])
        every = (np.column_stack([p1, np.ones(len(p1))]), p2)
        big, dist = lines_row(fig, grid, row, holder, f"your E's lines, {label}", F, truth_F, h1, p2[picked], ZOOM_PX,
                              every)
        ok = bool(np.all(np.isfinite(dist)))
        mean = float(np.mean(dist)) if ok else float("inf")
        far = line_distances(every[0] @ F.T, p2)
        largest = float(np.max(far)) if np.all(np.isfinite(far)) else float("inf")
        measures[f"{prefix}mean_distance_px"] = mean
        measures[f"{prefix}max_distance_px"] = float(np.max(dist)) if ok else float("inf")
        measures[f"{prefix}largest_miss_px"] = largest
        measures[f"{prefix}true_F_mean_distance_px"] = float(np.mean(line_distances(h1 @ truth_F.T, p2[picked])))
        h, w = holder.im2.shape[:2]
        measures[f"{prefix}lines_in_image"] = float(sum(clip_line(ln, w, h) is not None for ln in h1 @ F.T))
        if row < len(Es) - 1:
            big.tick_params(labelbottom=False)   # its x labels ran into the next row's title
        # one line at 8 pt: a second would run into the zooms' row above, 9 pt past the panel into its
        # first zoom (how many lines cross the image is in the alt)
        big.set_title(f"{label}: dots {measure_text(mean, 'px')} from your lines, up to {measure_text(largest, 'px')}", fontsize=8)
        parts.append(f"{label}: {measure_text(mean, 'px')}")
        parts_far.append(f"{label}: {measure_text(largest, 'px')}")
    alt = (f"Image 2 with {N_DRAWN} epipolar lines of the F your E implies (K2^-T E K1^-1; solid, orange) and of the "
           f"true F (dashed, blue) through the true matches (red dots); a red stick from each true match towards its "
           f"line, {MISS_MAGNIFY:g} times its distance; and zooms of at least {ZOOM_PX} px on the {N_ZOOMED} matches "
           "farthest from their lines, the farthest framed in purple; for the temple and for the self-check's pair "
           "(drawn on a blank image 2 of 640 x 480). Mean distance of the dots to your lines: "
           + "; ".join(parts)
           + ". Largest distance of a true match to its line: " + "; ".join(parts_far)
           + f". {int(measures['lines_in_image'])} of your {N_DRAWN} lines cross the temple's image 2."
           + (" On the temple K1 == K2, so K1 and K2 swapped, or one K used on both sides, give the right E there; "
              "the pair with K1 != K2 shows them." if same_k else ""))
    return to_picture("Q3.1", "essentialMatrix: the epipolar lines your E implies", fig, alt, measures)
