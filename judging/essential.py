"""Q3.1, ``essentialMatrix(F, K1, K2) -> E``: E = K2^T F K1, up to scale and sign."""

from __future__ import annotations

import numpy as np

from .mistakes import essential_mistakes, same_up_to_scale
from .verdict import Verdict, fmt, read_array

__all__ = ["RTOL", "essential", "read_E", "singular_values"]

RTOL = 1e-6   # largest difference of the unit-norm matrices (and of singular value ratios)


def read_E(value) -> np.ndarray:
    """E (3, 3) from a returned value, or Malformed."""
    return read_array(value, (3, 3), "E")


def _gap(E, G) -> float:
    a, b = E / np.linalg.norm(E), G / np.linalg.norm(G)
    return float(min(np.abs(a - b).max(), np.abs(a + b).max()))


def essential(E, F, K1, K2) -> Verdict:
    """E (3, 3) equals K2^T F K1 up to scale and sign (F, K1, K2 (3, 3) the inputs); names the formula used."""
    what = "E is the essential matrix of F, K1 and K2 (up to scale)"
    E, F, K1, K2 = (np.asarray(a, float) for a in (E, F, K1, K2))
    expected = K2.T @ F @ K1
    if not (np.all(np.isfinite(E)) and np.any(E)):
        return Verdict.of(what, False, "E is zero or not finite", f"difference <= {RTOL:g}")
    ok = same_up_to_scale(E, expected, RTOL)
    return Verdict.of(what, ok, f"largest difference of the unit-norm matrices {fmt(_gap(E, expected))}",
                      f"<= {RTOL:g}", () if ok else essential_mistakes(E, F, K1, K2, RTOL))


def singular_values(E) -> Verdict:
    """E (3, 3) of a true F has two equal singular values and a zero one (to RTOL of s1)."""
    what = "two equal singular values and a zero one"
    E = np.asarray(E, float)
    if not (np.all(np.isfinite(E)) and np.any(E)):
        return Verdict.of(what, False, "E is zero or not finite", f"both <= {RTOL:g}")
    s = np.linalg.svd(E, compute_uv=False)
    gap, last = 1.0 - s[1] / s[0], s[2] / s[0]
    return Verdict.of(what, gap <= RTOL and last <= RTOL, f"1 - s2/s1 = {fmt(gap)}, s3/s1 = {fmt(last)}",
                      f"both <= {RTOL:g}")
