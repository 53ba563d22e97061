"""A still camera of calibration.json in the forms vision libraries read.

- OpenCV FileStorage YAML (``cv2.FileStorage`` reads it): ``image_width``, ``image_height``,
  ``camera_matrix`` (3x3), ``distortion_coefficients`` (1xn, OpenCV order k1 k2 p1 p2 k3),
  ``T_robot_camera`` (4x4, mm: camera frame (OpenCV's) -> robot frame, ``docs/format.md``)
  and ``T_robot_camera_std_mm`` / ``_deg`` (translation, rotation; one standard deviation).
- ROS ``camera_info`` YAML (the ``camera_calibration_parsers`` layout: ``image_width``,
  ``camera_matrix``, ``distortion_model: plumb_bob``, ``distortion_coefficients``,
  ``rectification_matrix``, ``projection_matrix``) plus, beside it,
  ``<stem>.transform.yaml``: the robot -> camera optical frame transform as ROS wants it
  (metres, quaternion x y z w), with the ``static_transform_publisher`` command line.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import yaml

from vision_cal.camera.fixed import FixedCamera
from vision_cal.dataset.io import atomic_write_text

ROBOT_FRAME = "robot_base"
CAMERA_FRAME = "camera_optical_frame"


def opencv_text(cam: FixedCamera) -> str:
    fs = cv2.FileStorage("camera.yaml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY
                         | cv2.FILE_STORAGE_FORMAT_YAML)
    fs.write("image_width", int(cam.size_px[0]))
    fs.write("image_height", int(cam.size_px[1]))
    fs.write("camera_matrix", np.asarray(cam.K, np.float64))
    fs.write("distortion_coefficients", np.asarray(cam.dist, np.float64).reshape(1, -1))
    fs.write("T_robot_camera", np.asarray(cam.T_robot_camera, np.float64))
    sd = cam.std
    fs.write("T_robot_camera_std_mm", np.asarray(sd[3:6], np.float64).reshape(1, 3))
    fs.write("T_robot_camera_std_deg", np.asarray(sd[:3], np.float64).reshape(1, 3))
    fs.write("intrinsics", cam.intrinsics)
    return fs.releaseAndGetString()


def write_opencv(path, cam: FixedCamera) -> Path:
    return atomic_write_text(path, opencv_text(cam))


def quaternion_xyzw(R: np.ndarray) -> list[float]:
    """Unit quaternion (x, y, z, w) of a rotation matrix (3, 3), w >= 0."""
    R = np.asarray(R, float)
    w = np.sqrt(max(0.0, 1.0 + R[0, 0] + R[1, 1] + R[2, 2])) / 2
    x = np.sqrt(max(0.0, 1.0 + R[0, 0] - R[1, 1] - R[2, 2])) / 2
    y = np.sqrt(max(0.0, 1.0 - R[0, 0] + R[1, 1] - R[2, 2])) / 2
    z = np.sqrt(max(0.0, 1.0 - R[0, 0] - R[1, 1] + R[2, 2])) / 2
    x = np.copysign(x, R[2, 1] - R[1, 2])
    y = np.copysign(y, R[0, 2] - R[2, 0])
    z = np.copysign(z, R[1, 0] - R[0, 1])
    q = np.array([x, y, z, w])
    return (q / np.linalg.norm(q)).tolist()


def ros_camera_info(cam: FixedCamera, *, name: str = "vision_cal") -> dict:
    K = np.asarray(cam.K, float)
    P = np.zeros((3, 4))
    P[:, :3] = K
    d = [float(v) for v in cam.dist]
    return {"image_width": int(cam.size_px[0]), "image_height": int(cam.size_px[1]),
            "camera_name": name,
            "camera_matrix": {"rows": 3, "cols": 3, "data": K.ravel().tolist()},
            "distortion_model": "plumb_bob" if len(d) == 5 else "rational_polynomial",
            "distortion_coefficients": {"rows": 1, "cols": len(d), "data": d},
            "rectification_matrix": {"rows": 3, "cols": 3, "data": np.eye(3).ravel().tolist()},
            "projection_matrix": {"rows": 3, "cols": 4, "data": P.ravel().tolist()}}


def ros_transform(cam: FixedCamera) -> dict:
    T = np.asarray(cam.T_robot_camera, float)
    t_m = (T[:3, 3] / 1000.0).tolist()
    q = quaternion_xyzw(T[:3, :3])
    args = " ".join(f"{v:.9g}" for v in [*t_m, *q])
    return {"parent_frame": ROBOT_FRAME, "child_frame": CAMERA_FRAME,
            "translation_m": t_m, "rotation_xyzw": q,
            "std": {"translation_mm": cam.std[3:6].tolist(), "rotation_deg": cam.std[:3].tolist()},
            "static_transform_publisher": f"ros2 run tf2_ros static_transform_publisher {args} "
                                          f"{ROBOT_FRAME} {CAMERA_FRAME}"}


def transform_path(path) -> Path:
    p = Path(path)
    return p.with_name(p.stem + ".transform.yaml")


def write_ros(path, cam: FixedCamera) -> list[Path]:
    """camera_info YAML at ``path`` and the transform beside it; the paths written."""
    head = ("# camera_info for ROS (camera_calibration_parsers layout), written by vision-cal;\n"
            f"# the camera's pose in the robot frame: {transform_path(path).name}\n")
    a = atomic_write_text(path, head + yaml.safe_dump(ros_camera_info(cam), sort_keys=False))
    b = atomic_write_text(transform_path(path),
                          "# robot frame (docs/format.md) -> camera optical frame (OpenCV axes)\n"
                          + yaml.safe_dump(ros_transform(cam), sort_keys=False))
    return [a, b]
