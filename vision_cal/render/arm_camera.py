"""The world's camera carried by the true robot (its own code: never the estimator's).

From the contract (``docs/format.md``, "The robot frame and cameras"): the flange frame F
has its origin on the joint-4 axis in the sheet's plane, x along link 2 at commanded
``q4 = 0``, z up. Its origin is where the pen of a tool on the joint-4 axis would be,
``base + L1 [cos phi1, sin phi1] + L2 [cos(phi1+phi2), sin(phi1+phi2)]`` with the true link
angles (every joint effect of :class:`TrueRobot` included), and its x axis points at
``phi1 + phi2 + q4``: joint 4 is taken exact (its zero is part of ``T_flange_camera``).
A camera fixed to the flange sits at ``T_sheet_flange @ T_flange_camera``; a camera fixed to
link 2 is the same with ``q4 = 0`` for every photo.

``T_flange_camera_true`` draws a plausible mount (camera looking down from 150-250 mm,
off the axis by up to 40 mm, tilted a few degrees) from a generator; the truth of every
transform is returned so that truth.json-like records can hold it.
"""

from __future__ import annotations

import numpy as np

from vision_cal.render.truth_model import TrueRobot


def _rot_z(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    R = np.zeros((len(a), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R


def T_sheet_flange(robot: TrueRobot, q_deg, j4_deg, approach=None) -> np.ndarray:
    """(N, 4, 4) flange frame -> sheet frame for commands ``q_deg`` (N, 2), ``j4_deg`` (N,).

    The sheet is taken rigid (``robot.sheet_matrix`` must be the identity: a camera sees
    the printed sheet, and a shrunk sheet is not a rigid frame)."""
    if not np.allclose(robot.M, np.eye(2)):
        raise ValueError("a camera on the arm needs a rigid sheet (no sheet_affine)")
    q = np.array(q_deg, dtype=float, ndmin=2)
    link = robot.link_deg(q, approach)
    p = robot.arm_points(link)[:, 2]
    a = np.radians(link[:, 0] + robot.zero_deg[0] + link[:, 1] + robot.zero_deg[1]
                   + np.asarray(j4_deg, float).reshape(-1))
    T = np.tile(np.eye(4), (len(q), 1, 1))
    T[:, :3, :3] = _rot_z(a)
    T[:, :2, 3] = p
    return T


def T_cam_sheet(robot: TrueRobot, q_deg, j4_deg, T_flange_camera, approach=None) -> np.ndarray:
    """(N, 4, 4) sheet -> camera (OpenCV axes) of the arm's camera, for rendering."""
    T_sc = T_sheet_flange(robot, q_deg, j4_deg, approach) @ np.asarray(T_flange_camera, float)
    return np.linalg.inv(T_sc)


def T_flange_camera_true(rng=None, *, height_mm=(150.0, 250.0), offset_mm: float = 40.0,
                         tilt_deg: float = 4.0) -> np.ndarray:
    """A camera mount (4, 4) flange -> camera: looking down (camera z along -z of F) from a
    height drawn in ``height_mm``, off the joint-4 axis by up to ``offset_mm``, its axis
    tilted by up to ``tilt_deg`` and turned about it at random."""
    rng = np.random.default_rng(rng)
    down = np.diag([1.0, -1.0, -1.0])                   # camera x = F x, camera z = -F z
    yaw = rng.uniform(-np.pi, np.pi)
    Rz = _rot_z(np.array([yaw]))[0]
    ax = rng.normal(size=3)
    ax[2] = 0.0
    ax /= np.linalg.norm(ax)
    t = np.radians(rng.uniform(0, tilt_deg))
    Kx = np.array([[0, -ax[2], ax[1]], [ax[2], 0, -ax[0]], [-ax[1], ax[0], 0]])
    Rt = np.eye(3) + np.sin(t) * Kx + (1 - np.cos(t)) * Kx @ Kx
    T = np.eye(4)
    T[:3, :3] = Rt @ Rz @ down
    r = rng.uniform(0, offset_mm)
    b = rng.uniform(-np.pi, np.pi)
    T[:3, 3] = [r * np.cos(b), r * np.sin(b), rng.uniform(*height_mm)]
    return T
