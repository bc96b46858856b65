"""The minimisation behind ``refineF``: Powell's method on the symmetric epipolar distance.

Its own module because the grader's sandbox never ships it (``core.shipping.SANDBOX_WITHHELD``):
there the kit's ``refineF`` asks the grader for this result instead of computing it, so code under
test cannot switch the polish back on for the run that has refineF switched off
(``core.refine_switch``).  Students get it with the rest of ``starter`` and call it through
``refineF`` only.
"""

from __future__ import annotations

import numpy as np
import scipy.optimize

from core import geometry
from core.geometry import enforce_rank2

__all__ = ["polish"]


def polish(F: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
    """The rank-2 F (3, 3), unit Frobenius norm, that Powell's method reaches from ``F``.

    F : (3, 3) finite, non-zero float array, x2^T F x1 = 0 in the coordinates of p1/p2.
    p1, p2 : (N, 2) float points (x, y) in those coordinates, N >= 8, already checked.
    """
    of = geometry.symmetric_epipolar_cost_of(p1, p2)

    def cost(f):
        return of(enforce_rank2(f.reshape(3, 3)))

    # Powell needs no gradient, and the cost is flat along F's scale: that is harmless to it.
    res = scipy.optimize.minimize(cost, (F / np.linalg.norm(F)).ravel(), method="Powell",
                                  options={"maxiter": 100000, "maxfev": 10000, "xtol": 1e-4, "ftol": 1e-4})
    out = enforce_rank2(res.x.reshape(3, 3))
    return out / np.linalg.norm(out)
