"""The measures of the pictures in words: one home for what each ``Picture.measures`` key means
and its unit, so that every page a student reads names a measure the same way.

:func:`label` (question, key) -> (words, unit); :func:`shown` (question, key, value) -> the value
in that unit ("12.3 px", "85 %", "candidate M2s[:, :, 2]").  A key of a run beside the main one
carries a prefix (``refineF_off_``, ``uint16_``, ``twisted_``, ``k_differ_``), said in words first.
A key this table does not know is shown with its underscores as spaces, never dropped.
"""

from __future__ import annotations

import math

__all__ = ["label", "shown"]

_PREFIXES = (("refineF_off_", "with refineF switched off, "), ("uint16_", "from uint16 points, "),
             ("twisted_", "twisted-pair case, "), ("k_differ_", "pair with K1 ≠ K2, "))

_LINES = {
    "n_lines": ("epipolar lines drawn", ""),
    "mean_distance_px": ("mean distance of the true matches to your epipolar lines", "px"),
    "max_distance_px": ("largest distance of a true match to your epipolar line", "px"),
    "largest_miss_px": ("largest distance of any true match to its epipolar line (the first zoom)", "px"),
    "true_F_mean_distance_px": ("mean distance of the true matches to the true F's lines (the noise)", "px"),
    "lines_in_image": ("your epipolar lines that cross image 2", ""),
}
# question -> key -> (words, unit); unit "%" for a share in [0, 1], "index" for a candidate M2s[:, :, k]
_WORDS: dict[str, dict[str, tuple[str, str]]] = {
    "Q2": {**_LINES,
           "uint16_F_change": ("change of your F when the points are uint16 (0: the same up to scale)", ""),
           "s3_over_s2": ("smallest over middle singular value of your F (0 when rank 2)", ""),
           "crossings_spread_px": ("spread of the points where your lines cross (0 when they meet in one epipole)",
                                   "px")},
    "Q3.1": {**_LINES, "K1_equals_K2": ("the temple's K1 equals its K2 (1: yes, 0: no)", "")},
    "Q3.2": {"mean_reprojection_px_1": ("mean reprojection distance in image 1", "px"),
             "mean_reprojection_px_2": ("mean reprojection distance in image 2", "px"),
             "err_reported": ("the err your triangulate returned", "px²"),
             "sum_of_squares": ("sum of the squared reprojection distances, recomputed", "px²"),
             "share_in_front": ("your points in front of both cameras", "%"),
             "magnified": ("offsets drawn magnified by", "×")},
    "Q3.3": {"chosen": ("the candidate your findM2 returned", "index"),
             "chosen_gap_deg": ("angle from your M2 to that candidate", "°"),
             "right": ("the right candidate (points in front of both cameras)", "index"),
             "chosen_share_in_front": ("points in front of both cameras under yours", "%"),
             "chosen_share_front_1_only": ("points in front of camera 1 only under yours", "%"),
             "right_share_in_front": ("points in front of both cameras under the right one", "%")},
    "Q4.1": {"mean_distance_px": ("mean distance of your matches to the true ones", "px"),
             "median_distance_px": ("median distance of your matches to the true ones", "px"),
             "share_within_tol": ("your matches within the tolerance", "%"),
             "tol_px": ("tolerance", "px"),
             "n_points": ("points matched", "")},
    "Q4.2": {"temple_size": ("size of the true temple (RMS distance to its centre)", "scene units"),
             "median_error": ("median distance of your points to the true ones, after the best similarity",
                              "scene units"),
             "share_near": ("your points near the true ones (within 5 % of the temple's size)", "%"),
             "scale": ("scale of that similarity", ""),
             "n_finite": ("your points that are numbers", ""),
             "route": ("how your points were got (0: compute3D_pts; 1: the 2022-24 compute3D_pts, with your "
                       "findM2; 2: your matcher and triangulate)", "")},
    "Q5": {"start_error": ("reprojection error at the start", "px²"),
           "end_error": ("reprojection error of the M2 and w you returned, recomputed", "px²"),
           "o1_reported": ("the o1 you returned", "px²"),
           "o2_reported": ("the o2 you returned", "px²"),
           "n_calls": ("calls of the objective recorded", ""),
           "history_first": ("first objective value recorded", ""),
           "history_min": ("lowest objective value recorded", ""),
           "t_ratio": ("|t| returned over |t| at the start", ""),
           "residual_layout_gap": ("gap of your residuals at the start from the handout's layout (0: the same)", "")},
    "Q6": {"mean_reprojection_px": ("mean reprojection distance of your keypoints", "px"),
           "n_reconstructed": ("keypoints reconstructed", ""),
           "mean_error_3d": ("mean distance of your keypoints to the true ones", "world units"),
           "err_reported": ("the err you returned", "px²"),
           "sum_of_squares": ("sum of the squared distances of your keypoints to the detections above Thres, "
                              "recomputed", "px²"),
           "nearest_rule": ("the threshold rule your points follow (its number; -1: none)", ""),
           "detections_at_thres": ("detections whose confidence is exactly Thres", ""),
           "n_left_out": ("keypoints the handout's rule reconstructs and yours leaves out", ""),
           "n_off_rule": ("your keypoints that follow detections the handout's rule leaves out", "")},
}


def label(question: str, key: str) -> tuple[str, str]:
    """(words, unit) of measure ``key`` of ``question``'s picture (see the module docstring)."""
    key = str(key)
    table = _WORDS.get(question, {})
    if key in table:
        return table[key]
    for prefix, said in _PREFIXES:
        if key.startswith(prefix) and key[len(prefix):] in table:
            words, unit = table[key[len(prefix):]]
            return said + words, unit
    if question == "Q6" and key.startswith("gap_"):
        return f"distance of your keypoints to those of rule {key[4:]}, where the rules differ", "world units"
    return key.replace("_", " "), ""


def shown(question: str, key: str, value: float) -> str:
    """``value`` of measure ``key`` in its unit, for a reader ("12.3 px", "85 %", "M2s[:, :, 2]")."""
    _, unit = label(question, key)
    value = float(value)
    if not math.isfinite(value):
        return "not finite"
    if unit == "%":
        return f"{100 * value:.3g} %"
    if unit == "index":
        return f"M2s[:, :, {int(value)}]" if value >= 0 else "none of the four"
    return f"{value:.4g}" + (f" {unit}" if unit else "")
