"""What the hand-eye tests and ``bench/handeye6.py`` share beside the program: a pose's
offset from the truth (in ``handeye_lsq.compose``'s terms) and the located camera of a fit
held in memory (the program reads it from calibration.json)."""

import numpy as np
from scipy.spatial.transform import Rotation

from vision_cal.camera.handeye_locate import FlangeCamera
from vision_cal.errors import VisionCalError


def pose_offset(T0: np.ndarray, T: np.ndarray) -> np.ndarray:
    """The (6,) ``d`` with ``handeye_lsq.compose(T0, d) == T``."""
    w = Rotation.from_matrix(T[:3, :3] @ T0[:3, :3].T).as_rotvec()
    return np.r_[np.degrees(w), T[:3, 3] - T0[:3, 3]]


def from_fit(fit) -> FlangeCamera:
    """The :class:`~vision_cal.camera.handeye_locate.FlangeCamera` of a
    :class:`vision_cal.camera.handeye.HandeyeFit` held in memory (what
    calibration.json holds of it)."""
    if fit.mount != "arm":
        raise VisionCalError("a camera fixed in the robot's frame needs no flange pose",
                             field="--mount")
    return FlangeCamera(fit.X, fit.Y, fit.lens, fit.free, tuple(fit.size_px), fit.cov,
                        fit.inflation ** 2 * fit.noise.pose_variances(),
                        "declared" if fit.declared else "estimated",
                        tuple(v.name for v in fit.views), fit.shared)
