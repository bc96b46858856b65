"""What every concept's inputs share: the first camera M1 = [I | 0] and the seconds a student
function may take per input (``SECONDS``, times the config's time_scale), so that the session's
budget is the sum of what the tests will ask for (``call_seconds`` in the package)."""

from __future__ import annotations

import numpy as np

__all__ = ["M1", "SECONDS"]

M1 = np.hstack([np.eye(3), np.zeros((3, 1))])

SECONDS = {
    "eightpoint": 5.0, "essentialMatrix": 2.0, "triangulate": 3.0, "findM2": 5.0,
    "epipolarCorrespondence": 0.5, "compute3D_pts.triangulate": 5.0,
    "rodriguesResidual": 2.0, "bundleAdjustment": 60.0, "MultiviewReconstruction": 5.0,
    "plot_3d_keypoint_video": 30.0,
}
