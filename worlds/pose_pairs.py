"""Pose pairs from the world (its own code: never the estimator's): what another tool (a
controller and a board detector) would hand to ``vision-cal handeye --poses``.

The true robot (:class:`TrueRobot`, every joint effect) stands at each command; the
controller reports its flange ``T_robot_flange`` in the robot frame R of the contract
(``p_S = base + Rot(z1) p_R``; the flange frame F: origin on the joint-4 axis in the sheet's
plane, x at ``phi1 + phi2 + q4``, z up). The target is a board lying on the sheet
(``T_sheet_target``), or riding on the flange for a fixed camera. ``T_camera_target`` is
what the camera sees: either the board's corners projected through a pinhole ``K``, moved
by ``noise_px`` and solved by OpenCV's ``solvePnP`` (a detector's pose, ``noise_px`` of
corner noise), or the true pose turned by ``noise_deg`` and moved by ``noise_mm`` per axis.
"""

from __future__ import annotations

import cv2
import numpy as np

from vision_cal.world.arm_camera import T_flange_camera_true, T_sheet_flange
from vision_cal.world.truth_model import TrueRobot


def T_sheet_robot(robot: TrueRobot) -> np.ndarray:
    """The robot frame R in the sheet frame (the contract's ``p_S = base + Rot(z1) p_R``)."""
    a = np.radians(robot.zero_deg[0])
    T = np.eye(4)
    T[:2, :2] = [[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]
    T[:2, 3] = robot.base_mm
    return T


def board_points(cols: int = 7, rows: int = 5, pitch_mm: float = 10.0) -> np.ndarray:
    """A board's corners in its own frame (z = 0, centred), (cols * rows, 3) mm."""
    u, v = np.meshgrid((np.arange(cols) - (cols - 1) / 2) * pitch_mm,
                       (np.arange(rows) - (rows - 1) / 2) * pitch_mm)
    return np.column_stack([u.ravel(), v.ravel(), np.zeros(u.size)])


def _rotvec(v) -> np.ndarray:
    R, _ = cv2.Rodrigues(np.asarray(v, float).reshape(3, 1))
    return R


def _seen(T_cam_target, K, noise_px, noise_mm, noise_deg, rng, board) -> np.ndarray:
    """What the camera reports for the true ``T_cam_target``."""
    if noise_px is not None:
        P = board @ T_cam_target[:3, :3].T + T_cam_target[:3, 3]
        uv = P[:, :2] / P[:, 2:3] * K[0, 0] + K[:2, 2]
        uv = uv + rng.normal(0.0, noise_px, uv.shape)
        rv0, _ = cv2.Rodrigues(T_cam_target[:3, :3])
        ok, rv, tv = cv2.solvePnP(board, uv, K, None, rv0, T_cam_target[:3, 3].copy(),
                                  useExtrinsicGuess=True, flags=cv2.SOLVEPNP_ITERATIVE)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = _rotvec(rv), tv.ravel()
        return T
    T = T_cam_target.copy()
    T[:3, :3] = T[:3, :3] @ _rotvec(np.radians(rng.normal(0.0, noise_deg, 3)))
    T[:3, 3] += rng.normal(0.0, noise_mm, 3)
    return T


def simulate_pairs(robot: TrueRobot, n: int, *, seed: int = 0, mount: str = "arm",
                   noise_px: float | None = 0.1, noise_mm: float = 0.0,
                   noise_deg: float = 0.0, f_px: float = 900.0, K=None,
                   X=None, board_at_mm=(0.0, 0.0), reach_mm: float = 60.0,
                   commands=None) -> dict:
    """``n`` pairs with the truth: ``{"A": (n, 4, 4) T_robot_flange, "B": (n, 4, 4)
    T_camera_target, "X": the true T_flange_camera or T_robot_camera, "Y": the true
    T_robot_target or T_flange_target, "q": (n, 2), "j4": (n,)}``.

    ``mount="arm"``: a camera drawn by :func:`T_flange_camera_true` looks down at a board
    lying flat at ``board_at_mm`` on the sheet; each pose puts the camera's view of the
    sheet within ``reach_mm`` of the board, joint 4 turned at random. ``mount="fixed"``: a
    camera 600 mm above ``board_at_mm`` looks down at a board (160 x 120 mm) riding 30 mm off
    the flange. ``commands`` ((M, 3) q1, q2, j4 in degrees): the arm's commands, taken in
    turn (those whose view misses the board skipped), instead of drawn at random."""
    rng = np.random.default_rng(seed)
    K = np.array([[f_px, 0, 399.5], [0, f_px, 299.5], [0, 0, 1.0]]) if K is None else K
    # a board sized to the view: 60 x 40 mm under a camera 150-250 mm away, 160 x 120 mm
    # under one 600 mm away (a quarter of the image wide either way)
    board = board_points() if mount == "arm" else board_points(9, 7, 20.0)
    T_sr = T_sheet_robot(robot)
    T_rs = np.linalg.inv(T_sr)
    centre = np.array([*board_at_mm, 0.0])
    if mount == "arm":
        X = T_flange_camera_true(rng) if X is None else np.asarray(X, float)
        T_sheet_target = np.eye(4)
        T_sheet_target[:3, 3] = centre
        Y = T_rs @ T_sheet_target
    else:
        X = np.eye(4) if X is None else np.asarray(X, float)
        if X is None or np.allclose(X, np.eye(4)):
            X = np.eye(4)
            X[:3, :3] = np.diag([1.0, -1.0, -1.0])          # looking straight down
            X[:3, 3] = (T_rs @ np.append(centre, 1.0))[:3] + [0.0, 0.0, 600.0]
        Y = np.eye(4)
        Y[:3, 3] = [30.0, 0.0, 0.0]
    q_all, j4_all, A_all, B_all = [], [], [], []
    tries = 0
    while len(A_all) < n:
        tries += 1
        if tries > 500 * n:
            raise ValueError(f"only {len(A_all)} of {n} poses see the board")
        if commands is not None:
            if tries > len(commands):
                raise ValueError(f"only {len(A_all)} of {n} commands see the board")
            q, j4 = np.asarray(commands[tries - 1][:2], float), float(commands[tries - 1][2])
        else:
            q = np.array([rng.uniform(-120, 120), rng.uniform(-150, 150)])
            if abs(q[1]) < 20:
                continue
            j4 = float(rng.uniform(-170, 170))
        T_sf = T_sheet_flange(robot, q[None], np.array([j4]))[0]
        A = T_rs @ T_sf
        if mount == "arm":
            T_st_cam = T_sf @ X
            # where the optical axis meets the sheet
            o, d = T_st_cam[:3, 3], T_st_cam[:3, 2]
            if d[2] > -0.5:
                continue
            hit = o - d * o[2] / d[2]
            if np.linalg.norm(hit[:2] - centre[:2]) > reach_mm:
                continue
            T_ct = np.linalg.inv(A @ X) @ Y
        else:
            if np.linalg.norm(T_sf[:2, 3] - centre[:2]) > 150.0:
                continue
            T_ct = np.linalg.inv(X) @ A @ Y
        P = board @ T_ct[:3, :3].T + T_ct[:3, 3]
        if np.any(P[:, 2] < 50):
            continue
        uv = P[:, :2] / P[:, 2:3] * K[0, 0] + K[:2, 2]
        if np.any(uv < 5) or np.any(uv[:, 0] > 794) or np.any(uv[:, 1] > 594):
            continue
        q_all.append(q)
        j4_all.append(j4)
        A_all.append(A)
        B_all.append(_seen(T_ct, K, noise_px, noise_mm, noise_deg, rng, board))
    return {"A": np.array(A_all), "B": np.array(B_all), "X": X, "Y": Y,
            "q": np.array(q_all), "j4": np.array(j4_all), "K": K}


def simulate_many_pairs(robot: TrueRobot, n: int, *, seed: int = 0, noise_px: float = 0.1,
                        f_px: float = 900.0, reach_mm: float = 60.0, X=None) -> dict:
    """:func:`simulate_pairs`' arm-mounted camera for thousands of pairs (benches of the
    fit's cost): the commands drawn and screened in batches (the same rules: both elbows,
    joint 4 at random, the view within ``reach_mm`` of the board, every corner in the
    image), each board pose then seen through PnP with ``noise_px``. Its draws are its
    own: the same ``seed`` gives other pairs than :func:`simulate_pairs`; ``X`` the camera
    on the flange (None: drawn); returns :func:`simulate_pairs`' keys."""
    rng = np.random.default_rng(seed)
    K = np.array([[f_px, 0, 399.5], [0, f_px, 299.5], [0, 0, 1.0]])
    board = board_points()
    X = T_flange_camera_true(rng) if X is None else np.asarray(X, float)
    T_rs = np.linalg.inv(T_sheet_robot(robot))
    Y = T_rs.copy()
    A_all, B_all, q_all, j4_all = [], [], [], []
    while sum(len(a) for a in A_all) < n:
        m = 50 * n
        q = np.column_stack([rng.uniform(-120, 120, m), rng.uniform(-150, 150, m)])
        j4 = rng.uniform(-170, 170, m)
        keep = np.abs(q[:, 1]) >= 20
        q, j4 = q[keep], j4[keep]
        T_sf = T_sheet_flange(robot, q, j4)
        T_sc = T_sf @ X
        o, d = T_sc[:, :3, 3], T_sc[:, :3, 2]
        ok = d[:, 2] < -0.5
        hit = o - d * (o[:, 2] / np.where(ok, d[:, 2], -1.0))[:, None]
        ok &= np.linalg.norm(hit[:, :2], axis=1) <= reach_mm
        T_ct = np.linalg.inv(T_rs @ T_sc[ok]) @ Y
        P = np.einsum("nij,kj->nki", T_ct[:, :3, :3], board) + T_ct[:, None, :3, 3]
        uv = P[..., :2] / P[..., 2:3] * K[0, 0] + K[:2, 2]
        good = (np.all(P[..., 2] >= 50, axis=1) & np.all(uv >= 5, axis=(1, 2))
                & np.all(uv[..., 0] <= 794, axis=1) & np.all(uv[..., 1] <= 594, axis=1))
        A_all.append((T_rs @ T_sf[ok])[good])
        B_all.append(T_ct[good])
        q_all.append(q[ok][good])
        j4_all.append(j4[ok][good])
    A = np.concatenate(A_all)[:n]
    B = np.array([_seen(T, K, noise_px, 0.0, 0.0, rng, board) for T in np.concatenate(B_all)[:n]])
    return {"A": A, "B": B, "X": X, "Y": Y, "K": K, "q": np.concatenate(q_all)[:n],
            "j4": np.concatenate(j4_all)[:n]}
