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

from pathlib import Path

import numpy as np

from vision_cal.dataset.io import atomic_write_bytes, atomic_write_json
from vision_cal.world.camera import distort_image, ideal_K
from vision_cal.world.dataset import encode_image
from vision_cal.world.photo import Photographer
from vision_cal.world.sheet import make_sheet, sheet_texture
from vision_cal.world.truth_model import TrueRobot


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


def T_flange_camera_true(rng=None, *, height_mm=(150.0, 250.0), offset_mm: float = 40.0,
                         tilt_deg=4.0) -> np.ndarray:
    """A camera mount (4, 4) flange -> camera: looking down (camera z along -z of F) from a
    height drawn in ``height_mm``, off the joint-4 axis by up to ``offset_mm``, its axis
    tilted by up to ``tilt_deg`` (or by a tilt drawn in a (lo, hi) pair) and turned about
    it at random."""
    rng = np.random.default_rng(rng)
    down = np.diag([1.0, -1.0, -1.0])                   # camera x = F x, camera z = -F z
    yaw = rng.uniform(-np.pi, np.pi)
    Rz = _rot_z(np.array([yaw]))[0]
    ax = rng.normal(size=3)
    ax[2] = 0.0
    ax /= np.linalg.norm(ax)
    lo, hi = (0.0, tilt_deg) if np.isscalar(tilt_deg) else tilt_deg
    t = np.radians(rng.uniform(lo, hi))
    Kx = np.array([[0, -ax[2], ax[1]], [ax[2], 0, -ax[0]], [-ax[1], ax[0], 0]])
    Rt = np.eye(3) + np.sin(t) * Kx + (1 - np.cos(t)) * Kx @ Kx
    T = np.eye(4)
    T[:3, :3] = Rt @ Rz @ down
    r = rng.uniform(0, offset_mm)
    b = rng.uniform(-np.pi, np.pi)
    T[:3, 3] = [r * np.cos(b), r * np.sin(b), rng.uniform(*height_mm)]
    return T


def field_sheet(*, size_mm=(594.0, 420.0), bottom_left_mm=(-297.0, -210.0), marker_mm=18.0,
                grid=(14, 10), margin_mm=12.0, dictionary="DICT_5X5_250"):
    """The marker field an arm camera sees piecewise: a dense ArUco grid over the sheet."""
    return make_sheet(size_mm=size_mm, bottom_left_mm=bottom_left_mm, dictionary=dictionary,
                      marker_mm=marker_mm, grid=grid, margin_mm=margin_mm)


def reachable_poses(robot: TrueRobot, n: int, rng, *, extent_mm, inset_mm: float = 60.0,
                    turn_j4: bool = True) -> list[tuple[np.ndarray, float]]:
    """``n`` commands (q (2,), j4) whose flange lies over the sheet ``inset_mm`` inside its
    ``extent_mm`` (x0, y0, x1, y1), both elbows (|q2| > 20 deg), joint 4 turned at random."""
    x0, y0, x1, y1 = extent_mm
    out = []
    for _ in range(200 * n):
        q = np.array([rng.uniform(-180, 180), rng.uniform(-150, 150)])
        xy = robot.pen_mm(q[None], link=True)[0]
        if (x0 + inset_mm < xy[0] < x1 - inset_mm and y0 + inset_mm < xy[1] < y1 - inset_mm
                and abs(q[1]) > 20):
            out.append((q, float(rng.uniform(-170, 170)) if turn_j4 else 0.0))
            if len(out) == n:
                return out
    raise ValueError(f"only {len(out)} of {n} poses put the flange over the sheet")


def photograph_poses(folder, robot: TrueRobot, sheet, q, j4, files, X, *, K, size_px, rng,
                     repeatability_mm: float = 0.01, noise_sigma: float = 1.5,
                     px_per_mm: float = 8.0, photographer=None, approach=None,
                     dist=None) -> np.ndarray:
    """The camera ``X`` (flange -> camera) on the true ``robot`` photographs ``sheet`` at
    commands ``q`` (N, 2), ``j4`` (N,) into ``folder``/``files``; the flange misses its
    commanded place by ``repeatability_mm`` (per axis) in each photo; ``approach`` (N, 2)
    the joints' last motion signs (the robot's backlash), None: +1; ``dist`` the lens's
    distortion (OpenCV coefficients, None: a pinhole), applied to the supersampled ideal
    render, which (our own photographer) is wide enough to fill the photo's corners
    (``world.camera.ideal_K``: a real lens leaves no black corners, and markers cut by
    them are found pixels off). Returns the true ``T_cam_sheet`` (N, 4, 4)."""
    tex = sheet_texture(sheet, marks_xy_mm=np.zeros((0, 2)), px_per_mm=px_per_mm, rng=rng)
    own = photographer is None
    lens = dist is not None and np.any(dist)
    ph = (Photographer(size_px=size_px, K=ideal_K(size_px, K, dist) if lens else K)
          if own else photographer)
    # the robot's repeatability: each photo's flange off its commanded place (per axis)
    T_sf = T_sheet_flange(robot, q, j4, approach)
    T_sf[:, :2, 3] += rng.normal(0.0, repeatability_mm, (len(q), 2))
    Ts = np.linalg.inv(T_sf @ np.asarray(X, float))
    try:
        for name, T in zip(files, Ts):
            if own and lens:
                rgb = ph.photograph(tex, extent_mm=sheet.extent_mm, T_cam_sheet=T,
                                    noise_sigma=noise_sigma, rng=rng, dist=dist, K_dist=K)
            else:
                rgb = ph.photograph(tex, extent_mm=sheet.extent_mm, T_cam_sheet=T,
                                    noise_sigma=noise_sigma, rng=rng)
                if lens:
                    rgb = distort_image(np.asarray(rgb), K=K, dist=dist)
            atomic_write_bytes(folder / name, encode_image(np.asarray(rgb), None))
    finally:
        if own:
            ph.close()
    return Ts


def render_arm_dataset(folder, *, truth: dict, nominal: dict, n_poses: int = 16,
                       size_px=(800, 600), f_px: float = 900.0, seed: int = 0,
                       px_per_mm: float = 8.0, noise_sigma: float = 1.5,
                       mount: str = "flange", repeatability_mm: float = 0.01,
                       photographer=None, tilt_deg=4.0, declare_lens: bool = True,
                       dist=None, height_mm=(150.0, 250.0)):
    """Photos of the marker field by the camera on the true robot: session.json (``poses``,
    declared lens) and truth.json (``params``, ``T_flange_camera``, per photo
    ``T_cam_sheet``). ``truth`` / ``nominal``: the format's ``params`` blocks; the flange
    misses its commanded place by ``repeatability_mm`` (per axis, Gaussian) in each photo;
    the camera's axis is tilted by up to ``tilt_deg``; ``declare_lens=False`` leaves
    session.json's ``camera`` out; ``dist`` the lens's distortion (declared as it is),
    ``height_mm`` the range the camera's height above the flange is drawn from."""
    rng = np.random.default_rng(seed)
    dist5 = [0.0] * 5 if dist is None else [float(v) for v in dist]
    robot = TrueRobot.from_json(truth)
    sheet = field_sheet()
    X = T_flange_camera_true(rng, tilt_deg=tilt_deg, height_mm=height_mm)
    poses = reachable_poses(robot, n_poses, rng, extent_mm=sheet.extent_mm,
                            turn_j4=(mount == "flange"))
    w, h = size_px
    K = np.array([[f_px, 0, (w - 1) / 2], [0, f_px, (h - 1) / 2], [0, 0, 1.0]])
    q = np.array([p[0] for p in poses])
    j4 = np.array([p[1] for p in poses])
    files = [f"pose_{i:03d}.png" for i in range(len(q))]
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    Ts = photograph_poses(folder, robot, sheet, q, j4, files, X, K=K, size_px=size_px, rng=rng,
                          repeatability_mm=repeatability_mm, noise_sigma=noise_sigma,
                          px_per_mm=px_per_mm, photographer=photographer, dist=dist)
    session = {"format": "vision-cal/1", "sheet": sheet.to_json(),
               "robot": {**nominal, "home_deg": [0.0, 0.0]},
               "camera_mount": mount,
               "poses": [{"image": f, "joints_deg": [float(a), float(b)], "j4_deg": float(c)}
                         for f, (a, b), c in zip(files, q, j4)]}
    if declare_lens:
        session["camera"] = {"size_px": list(size_px), "K": K.tolist(), "dist": dist5}
    atomic_write_json(folder / "session.json", session)
    atomic_write_json(folder / "truth.json", {
        "params": truth, "T_flange_camera": X.tolist(), "repeatability_mm": repeatability_mm,
        "camera": {"K": K.tolist(), "dist": dist5,
                   "T_cam_sheet": {f: T.tolist() for f, T in zip(files, Ts)}}})
    return folder
