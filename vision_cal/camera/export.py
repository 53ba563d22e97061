"""A still camera of calibration.json, or a camera on any arm's flange, in the forms vision
libraries read.

- OpenCV FileStorage YAML (``cv2.FileStorage`` reads it): ``image_width``, ``image_height``,
  ``camera_matrix`` (3x3), ``distortion_coefficients`` (1xn, OpenCV order k1 k2 p1 p2 k3),
  ``T_robot_camera`` (4x4, mm: camera frame (OpenCV's) -> robot frame, ``docs/format.md``)
  and ``T_robot_camera_std_mm`` / ``_deg`` (translation, rotation; one standard deviation);
  a camera on the flange: ``T_flange_camera`` and its std instead, and ``T_robot_board``.
- ROS ``camera_info`` YAML (the ``camera_calibration_parsers`` layout: ``image_width``,
  ``camera_matrix``, ``distortion_model: plumb_bob``, ``distortion_coefficients``,
  ``rectification_matrix``, ``projection_matrix``) plus, beside it,
  ``<stem>.transform.yaml``: the robot -> camera optical frame transform as ROS wants it
  (metres, quaternion x y z w), with the ``static_transform_publisher`` command line; a
  camera on the flange: the flange (``tool0``: the frame whose poses the controller
  reported) -> camera optical frame, a static transform the arm's own tree carries.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml

from vision_cal.camera.fixed import FixedCamera
from vision_cal.dataset.io import atomic_write_text

ROBOT_FRAME = "robot_base"
FLANGE_FRAME = "tool0"
CAMERA_FRAME = "camera_optical_frame"


@dataclass(frozen=True)
class CameraPose:
    """What the files hold of a camera: its lens and its one transform ``name`` (4, 4, mm;
    from the camera frame to ``parent``) with its std (``std``: rotation deg about the
    parent's axes, translation mm); ``extra``: other transforms to write (name -> 4x4)."""

    size_px: tuple[int, int]
    K: np.ndarray
    dist: np.ndarray
    intrinsics: str
    name: str
    T: np.ndarray
    std: np.ndarray
    parent: str
    extra: tuple = ()


def pose_of(cam) -> CameraPose:
    """The :class:`CameraPose` of a still camera (:class:`FixedCamera`) or of a camera on
    any arm's flange (:class:`vision_cal.camera.handeye_locate.FlangeCamera`)."""
    if isinstance(cam, FixedCamera):
        return CameraPose(cam.size_px, cam.K, cam.dist, cam.intrinsics, "T_robot_camera",
                          cam.T_robot_camera, cam.std[:6], ROBOT_FRAME)
    sd = np.sqrt(np.clip(np.diag(cam.cov)[:6], 0.0, None))
    return CameraPose(cam.size_px, cam.K, cam.lens[4:], cam.intrinsics, "T_flange_camera",
                      cam.X, sd, FLANGE_FRAME, (("T_robot_board", cam.Y),))


def opencv_text(cam) -> str:
    c = pose_of(cam)
    fs = cv2.FileStorage("camera.yaml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY
                         | cv2.FILE_STORAGE_FORMAT_YAML)
    fs.write("image_width", int(c.size_px[0]))
    fs.write("image_height", int(c.size_px[1]))
    fs.write("camera_matrix", np.asarray(c.K, np.float64))
    fs.write("distortion_coefficients", np.asarray(c.dist, np.float64).reshape(1, -1))
    fs.write(c.name, np.asarray(c.T, np.float64))
    fs.write(f"{c.name}_std_mm", np.asarray(c.std[3:6], np.float64).reshape(1, 3))
    fs.write(f"{c.name}_std_deg", np.asarray(c.std[:3], np.float64).reshape(1, 3))
    for name, T in c.extra:
        fs.write(name, np.asarray(T, np.float64))
    fs.write("intrinsics", c.intrinsics)
    return fs.releaseAndGetString()


def write_opencv(path, cam) -> Path:
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


def ros_camera_info(cam, *, name: str = "vision_cal") -> dict:
    cam = pose_of(cam)
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


def ros_transform(cam) -> dict:
    c = pose_of(cam)
    T = np.asarray(c.T, float)
    t_m = (T[:3, 3] / 1000.0).tolist()
    q = quaternion_xyzw(T[:3, :3])
    args = " ".join(f"{v:.9g}" for v in [*t_m, *q])
    return {"parent_frame": c.parent, "child_frame": CAMERA_FRAME,
            "translation_m": t_m, "rotation_xyzw": q,
            "std": {"translation_mm": [float(v) for v in c.std[3:6]],
                    "rotation_deg": [float(v) for v in c.std[:3]]},
            "static_transform_publisher": f"ros2 run tf2_ros static_transform_publisher {args} "
                                          f"{c.parent} {CAMERA_FRAME}"}


def transform_path(path) -> Path:
    p = Path(path)
    return p.with_name(p.stem + ".transform.yaml")


def write_ros(path, cam) -> list[Path]:
    """camera_info YAML at ``path`` and the transform beside it; the paths written."""
    flange = pose_of(cam).parent == FLANGE_FRAME
    where = ("on the flange (tool0: the frame whose poses the controller reported)" if flange
             else "in the robot frame")
    head = ("# camera_info for ROS (camera_calibration_parsers layout), written by vision-cal;\n"
            f"# the camera's pose {where}: {transform_path(path).name}\n")
    a = atomic_write_text(path, head + yaml.safe_dump(ros_camera_info(cam), sort_keys=False))
    parent = ("the flange, tool0 (T_robot_flange as the controller reports it)" if flange
              else "robot frame (docs/format.md)")
    b = atomic_write_text(transform_path(path),
                          f"# {parent} -> camera optical frame (OpenCV axes)\n"
                          + yaml.safe_dump(ros_transform(cam), sort_keys=False))
    return [a, b]
