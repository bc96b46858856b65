"""Helpers given to students (the handout's helper functions) and data loading.

Students import from here; it holds no answer to any question.
"""

from .data import CarFrame, TempleData, car_times, data_root, load_car_frame, load_image, load_temple
from .epipolar import epipolar_distances, refineF
from .figures import Figure3D, plot_points_3d
from .interactive import EpipolarSession, displayEpipolarF, epipolar_line, epipolar_line_endpoints, epipolarMatchGUI
from .keypoints import plot_3d_keypoint, plot_3d_keypoint_frames, visualize_keypoints
from .pose import camera2
from .ransac import ransacF
from .rotations import invRodrigues, rodrigues
from core.skeleton import CAR_KEYPOINTS, CAR_SKELETON
from core.validate import DegenerateInputError

__all__ = [
    "refineF", "camera2", "ransacF", "rodrigues", "invRodrigues", "epipolar_distances",
    "load_temple", "load_car_frame", "car_times", "load_image", "data_root", "TempleData", "CarFrame",
    "CAR_KEYPOINTS", "CAR_SKELETON", "DegenerateInputError",
    "plot_points_3d", "Figure3D", "visualize_keypoints", "plot_3d_keypoint", "plot_3d_keypoint_frames",
    "displayEpipolarF", "epipolarMatchGUI", "epipolar_line", "epipolar_line_endpoints", "EpipolarSession",
]
