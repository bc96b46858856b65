"""Public self-checks for students: run one on your function to see what works and what does not.

Each ``check_<name>(your_function)`` runs your function on generated scenes whose answers are
known (and, for eightpoint, essentialMatrix and MultiviewReconstruction, on the default data in
data/ when it is there; the other checks would need a reference answer to use them), then prints one line per check (a
tick or a cross, the figure measured and the goal) and names any known mistake it recognises,
with a hint.  It returns a :class:`CheckReport` (``.passed``, ``.items``, ``.mistakes``).

>>> from starter.checks import check_eightpoint      # doctest: +SKIP
>>> check_eightpoint(eightpoint)                      # doctest: +SKIP

These are public checks: passing them promises nothing about the hidden tests.  They never use
OpenCV, so they say the same wherever they run (Colab has OpenCV, a local install may not).
"""

from judging.mistakes import KNOWN_MISTAKES, Mistake

from .bundle import check_bundleAdjustment, check_rodriguesResidual
from .correspondence import check_compute3D_pts, check_epipolarCorrespondence
from .essential import check_essentialMatrix
from .fundamental import check_eightpoint
from .multiview import check_MultiviewReconstruction
from .pose import check_findM2
from .report import CheckItem, CheckReport
from .triangulation import check_triangulate

__all__ = [
    "CHECKS",
    "KNOWN_MISTAKES",
    "CheckItem",
    "CheckReport",
    "Mistake",
    "check_MultiviewReconstruction",
    "check_bundleAdjustment",
    "check_compute3D_pts",
    "check_eightpoint",
    "check_epipolarCorrespondence",
    "check_essentialMatrix",
    "check_findM2",
    "check_rodriguesResidual",
    "check_triangulate",
]

# Each homework function's self-check, by the function's name (core.manifest's names).
CHECKS = {
    "eightpoint": check_eightpoint, "essentialMatrix": check_essentialMatrix, "triangulate": check_triangulate,
    "findM2": check_findM2, "epipolarCorrespondence": check_epipolarCorrespondence,
    "compute3D_pts": check_compute3D_pts, "rodriguesResidual": check_rodriguesResidual,
    "bundleAdjustment": check_bundleAdjustment, "MultiviewReconstruction": check_MultiviewReconstruction,
}
