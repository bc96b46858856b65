"""Reference solutions of the homework, under the handout's names.

Each module answers one question; the student notebooks, the answer key and the nbgrader source
are all built from these functions (python -m kit notebooks), so they are written only here.
"""

from .bundle import bundleAdjustment, rodriguesResidual
from .correspondence import compute3D_pts, epipolarCorrespondence
from .essential import essentialMatrix
from .fundamental import eightpoint
from .multiview import MultiviewReconstruction, plot_3d_keypoint_video
from .pose import findM2
from .triangulation import triangulate

__all__ = [
    "eightpoint", "essentialMatrix", "triangulate", "findM2", "epipolarCorrespondence", "compute3D_pts",
    "rodriguesResidual", "bundleAdjustment", "MultiviewReconstruction", "plot_3d_keypoint_video",
]
