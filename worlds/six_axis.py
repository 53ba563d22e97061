"""A six-axis arm's world for the hand-eye (its own code: never the estimator's).

A UR-like arm (standard Denavit-Hartenberg chain, :data:`UR5E_DH`) whose true geometry
differs from the controller's model by a few tenths of a millimetre and hundredths of a
degree (:func:`perturbed_arm`), and whose joints land a little off each command
(``joint_noise_deg``): the controller reports the flange where its model puts the
commanded joints (``T_robot_flange``), the board or the camera rides on the true flange.
A ChArUco board (OpenCV's own ``CharucoBoard``: its corners and its printed image), a lens
with distortion that the estimator is not told, and either

- the chessboard corners projected and moved by the detector's noise (:func:`observe`:
  cheap, for tests), or
- photographs (:func:`photograph`): the board's printed image mapped through the lens
  pixel by pixel (every output pixel traced back to the board's plane through the
  distortion, supersampled), blurred and noised, written with the poses as a user's
  folder (:func:`write_session`: ``images/N.png``, ``poses/N.yaml`` in metres with the
  quaternion, as ROS tools write them, and ``truth.json``).

Mounts: ``fixed`` (a still camera, the board on the flange: ``T_robot_camera``,
``T_flange_board``) or ``arm`` (the camera on the flange, the board still:
``T_flange_camera``, ``T_robot_board``). The board's frame is the sheet frame of
docs/format.md: origin at the board's centre, x right, y up, z out of the printed side;
OpenCV's board frame (origin top-left, y down, z into the board) is turned into it here.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import cv2
import numpy as np
from scipy.interpolate import RectBivariateSpline
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

#: a UR5e's nominal Denavit-Hartenberg chain (mm, deg; Universal Robots' published values)
UR5E_DH = {"a_mm": (0.0, -425.0, -392.2, 0.0, 0.0, 0.0),
           "d_mm": (162.5, 0.0, 0.0, 133.3, 99.7, 99.6),
           "alpha_deg": (90.0, 0.0, 0.0, 90.0, -90.0, 0.0),
           "theta0_deg": (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)}

#: the board of the real session (industrial_charuco_even): 5 x 7 squares, DICT_6X6_250
BOARD = {"squares": (5, 7), "square_mm": 36.195, "marker_mm": 18.256,
         "dictionary": "DICT_6X6_250"}


def _T(R=None, t=None) -> np.ndarray:
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if t is not None:
        T[:3, 3] = t
    return T


def _inv(T: np.ndarray) -> np.ndarray:
    R, t = T[:3, :3], T[:3, 3]
    return _T(R.T, -R.T @ t)


def _rot(rotvec_deg) -> np.ndarray:
    return Rotation.from_rotvec(np.radians(rotvec_deg)).as_matrix()


@dataclass(frozen=True)
class SixAxisArm:
    """A standard DH chain: joint i turns about z_{i-1} by ``theta0 + q``, then d along z,
    a along the new x, alpha about it (mm, deg)."""

    a_mm: tuple
    d_mm: tuple
    alpha_deg: tuple
    theta0_deg: tuple

    def flange(self, q_deg) -> np.ndarray:
        """T_robot_flange (4, 4, mm) at joints ``q_deg`` (6,)."""
        T = np.eye(4)
        for a, d, al, th0, q in zip(self.a_mm, self.d_mm, self.alpha_deg, self.theta0_deg,
                                    q_deg):
            th, al = np.radians(th0 + q), np.radians(al)
            ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
            T = T @ np.array([[ct, -st * ca, st * sa, a * ct],
                              [st, ct * ca, -ct * sa, a * st],
                              [0.0, sa, ca, d], [0.0, 0.0, 0.0, 1.0]])
        return T

    def solve(self, T_target: np.ndarray, q0) -> np.ndarray | None:
        """Joints reaching ``T_target`` from ``q0`` (deg), or None (not reached to 1e-6)."""
        def res(q):
            T = self.flange(q)
            dR = Rotation.from_matrix(T_target[:3, :3].T @ T[:3, :3]).as_rotvec()
            return np.r_[T[:3, 3] - T_target[:3, 3], 500.0 * dR]

        r = least_squares(res, np.asarray(q0, float), xtol=1e-12, ftol=1e-12, gtol=1e-12)
        if np.max(np.abs(r.fun)) > 1e-6:
            return None
        return (r.x + 180.0) % 360.0 - 180.0


def nominal_arm() -> SixAxisArm:
    return SixAxisArm(**{k: tuple(v) for k, v in UR5E_DH.items()})


def perturbed_arm(arm: SixAxisArm, rng, *, length_mm: float = 0.3,
                  angle_deg: float = 0.03) -> SixAxisArm:
    """The true arm: every DH length off by N(0, length_mm), every angle by N(0, angle_deg)."""
    def jig(v, s):
        return tuple(float(x) for x in np.asarray(v) + rng.normal(0.0, s, 6))

    return SixAxisArm(jig(arm.a_mm, length_mm), jig(arm.d_mm, length_mm),
                      jig(arm.alpha_deg, angle_deg), jig(arm.theta0_deg, angle_deg))


@dataclass(frozen=True)
class Lens:
    """OpenCV's pinhole with k1 k2 p1 p2 k3 (its own implementation here)."""

    K: np.ndarray
    dist: np.ndarray
    size_px: tuple[int, int]

    def project(self, P: np.ndarray) -> np.ndarray:
        """Camera-frame points (N, 3) -> pixels (N, 2)."""
        x, y = P[:, 0] / P[:, 2], P[:, 1] / P[:, 2]
        k1, k2, p1, p2, k3 = self.dist
        r2 = x * x + y * y
        rad = 1 + k1 * r2 + k2 * r2 ** 2 + k3 * r2 ** 3
        xd = x * rad + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yd = y * rad + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        return np.c_[self.K[0, 0] * xd + self.K[0, 1] * yd + self.K[0, 2],
                     self.K[1, 1] * yd + self.K[1, 2]]

    def to_json(self) -> dict:
        return {"size_px": list(self.size_px), "K": self.K.tolist(),
                "dist": [float(v) for v in self.dist]}


def random_lens(rng, size_px=(1600, 1200)) -> Lens:
    """An industrial camera's lens: f about 1.1 image widths... 0.85, a principal point
    within 2 % of the centre, barrel distortion."""
    w, h = size_px
    f = w * rng.uniform(0.8, 1.1)
    K = np.array([[f * rng.uniform(0.998, 1.002), 0.0, w / 2 + rng.normal(0, 0.02 * w)],
                  [0.0, f, h / 2 + rng.normal(0, 0.02 * h)], [0.0, 0.0, 1.0]])
    dist = np.array([rng.uniform(-0.2, -0.05), rng.uniform(0.0, 0.15), rng.normal(0, 5e-4),
                     rng.normal(0, 5e-4), 0.0])
    return Lens(K, dist, (int(w), int(h)))


@dataclass(frozen=True)
class Board:
    """The ChArUco board: OpenCV's object and its chessboard corners in the sheet frame."""

    squares: tuple[int, int]
    square_mm: float
    marker_mm: float
    dictionary: str

    def opencv(self):
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard(self.squares, self.square_mm, self.marker_mm, d)

    @property
    def size_mm(self) -> tuple[float, float]:
        return self.squares[0] * self.square_mm, self.squares[1] * self.square_mm

    def sheet_from_cv(self) -> np.ndarray:
        """T_sheet_cvboard: OpenCV's board frame in the sheet frame (x, y up, z out)."""
        W, H = self.size_mm
        return _T(np.diag([1.0, -1.0, -1.0]), [-W / 2.0, H / 2.0, 0.0])

    def corners(self) -> np.ndarray:
        """(N, 3) chessboard inner corners in the sheet frame, OpenCV's id order."""
        c = np.asarray(self.opencv().getChessboardCorners(), float).reshape(-1, 3)
        # float32 in OpenCV: rebuilt from the squares' indices in float64
        c = np.round(c / self.square_mm) * self.square_mm
        S = self.sheet_from_cv()
        return c @ S[:3, :3].T + S[:3, 3]


@dataclass(frozen=True)
class World:
    """One scene: the arm as modelled and as built, the mount's two unknowns, the lens and
    the board, and the controller's noise."""

    mount: str                      # fixed | arm
    nominal: SixAxisArm
    true: SixAxisArm
    X: np.ndarray                   # fixed: T_robot_camera; arm: T_flange_camera
    Y: np.ndarray                   # fixed: T_flange_board; arm: T_robot_board
    lens: Lens
    board: Board
    joint_noise_deg: float
    noise_px: float                 # the detector's corner noise (1 sigma, per axis)
    home_deg: tuple = (0.0, -90.0, 90.0, -90.0, -90.0, 0.0)
    extra: dict = field(default_factory=dict)

    def T_camera_board(self, q_true) -> np.ndarray:
        F = self.true.flange(q_true)
        if self.mount == "fixed":
            return _inv(self.X) @ F @ self.Y
        return _inv(self.X) @ _inv(F) @ self.Y

    def truth(self) -> dict:
        names = (("T_robot_camera", "T_flange_board") if self.mount == "fixed"
                 else ("T_flange_camera", "T_robot_board"))
        return {"format": "vision-cal/six-axis-truth/1", "mount": self.mount,
                names[0]: self.X.tolist(), names[1]: self.Y.tolist(),
                "camera": self.lens.to_json(), "joint_noise_deg": self.joint_noise_deg,
                "noise_px": self.noise_px, "board": {"squares": list(self.board.squares),
                                                     "square_mm": self.board.square_mm,
                                                     "marker_mm": self.board.marker_mm,
                                                     "dictionary": self.board.dictionary},
                "arm": {"nominal": self.nominal.__dict__, "true": self.true.__dict__}}


def make_world(seed: int, *, mount: str = "fixed", joint_noise_deg: float = 0.01,
               dh_error_mm: float = 0.0, dh_error_deg: float = 0.0, noise_px: float = 0.15,
               lens: Lens | None = None, board: dict | None = None) -> World:
    """A scene of ``seed``. Fixed: the camera about 1.1 m from the arm's base looking back
    at it, the board 120-180 mm out from the flange; arm: the camera 60-110 mm out from
    the flange looking along it, the board on the table 400-600 mm in front of the base."""
    rng = np.random.default_rng(seed)
    nominal = nominal_arm()
    true = perturbed_arm(nominal, rng, length_mm=dh_error_mm, angle_deg=dh_error_deg)
    lens = lens or random_lens(rng)
    b = Board(**{**BOARD, **(board or {})})
    if mount == "fixed":
        # the camera: 1.1 m out along x, 0.45 m up, looking back at (0.4, 0, 0.35) m
        eye = np.array([1100.0, rng.normal(0, 100), 450.0 + rng.normal(0, 50)])
        X = _look_at(eye, np.array([400.0, 0.0, 350.0]), rng)
        # the board: out along the flange's z, facing away from it, turned about z
        Y = _T(_rot([0.0, 180.0, rng.uniform(-180, 180)]) @ _rot(rng.normal(0, 5, 3)),
               [rng.normal(0, 20), rng.normal(0, 20), rng.uniform(120, 180)])
    elif mount == "arm":
        X = _T(_rot(rng.normal(0, 5, 3)) @ _rot([0.0, 0.0, rng.uniform(-180, 180)]),
               [rng.normal(0, 40), rng.normal(0, 40), rng.uniform(60, 110)])
        Y = _T(_rot([0.0, 0.0, rng.uniform(-180, 180)]),
               [rng.uniform(400, 600), rng.normal(0, 100), rng.uniform(-50, 50)])
    else:
        raise ValueError(f"mount {mount!r}")
    return World(mount, nominal, true, X, Y, lens, b, float(joint_noise_deg), float(noise_px))


def _look_at(eye, target, rng) -> np.ndarray:
    """A camera pose (OpenCV: z forward, y down) at ``eye`` looking at ``target``, rolled a
    little."""
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.c_[x, y, z] @ _rot([0.0, 0.0, rng.normal(0, 3)])
    return _T(R, eye)


def _desired_board_in_camera(world: World, rng) -> np.ndarray:
    """A board pose the camera sees whole: 500-1000 mm away (fixed) or 250-500 (arm),
    tilted 10-40 deg, turned about its normal, anywhere in the middle of the image."""
    far = (550.0, 950.0) if world.mount == "fixed" else (280.0, 480.0)
    z = rng.uniform(*far)
    w, h = world.lens.size_px
    u, v = rng.uniform(0.3, 0.7) * w, rng.uniform(0.3, 0.7) * h
    K = world.lens.K
    centre = np.array([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z])
    tilt = rng.uniform(10, 40)
    az = rng.uniform(0, 360)
    axis = np.array([np.cos(np.radians(az)), np.sin(np.radians(az)), 0.0])
    # the board faces the camera: its z (out of the print) towards -z of the camera
    R = _rot(axis * tilt) @ _rot([180.0, 0.0, 0.0]) @ _rot([0.0, 0.0, rng.uniform(-40, 40)])
    return _T(R, centre)


def sample_poses(world: World, n: int, rng, *, max_tries: int = 4000) -> np.ndarray:
    """(n, 6) commanded joints (deg) whose photos show the whole board, reached by the
    controller's model."""
    out: list = []
    board = world.board.corners()
    tries = 0
    while len(out) < n and tries < max_tries:
        tries += 1
        T_cb = _desired_board_in_camera(world, rng)
        if not _sees_board(world, T_cb, board):
            continue
        if world.mount == "fixed":
            T_rf = world.X @ T_cb @ _inv(world.Y)
        else:
            T_rf = world.Y @ _inv(T_cb) @ _inv(world.X)
        q0 = (out[-1] if out and rng.random() < 0.7 else np.asarray(world.home_deg)) \
            + rng.normal(0, 10, 6)
        q = world.nominal.solve(T_rf, q0)
        if q is None:
            continue
        out.append(q)
    if len(out) < n:
        raise RuntimeError(f"only {len(out)} of {n} poses reached in {max_tries} tries")
    return np.array(out)


def _sees_board(world: World, T_cb, board, margin_px: float = 20.0) -> bool:
    P = board @ T_cb[:3, :3].T + T_cb[:3, 3]
    if np.any(P[:, 2] <= 0) or T_cb[2, 2] > -0.2:
        return False
    uv = world.lens.project(P)
    w, h = world.lens.size_px
    return bool(np.all((uv > margin_px) & (uv < np.array([w, h]) - margin_px)))


@dataclass(frozen=True)
class Shot:
    """One photo's pose: the command, where the joints really went, the controller's report
    (T_robot_flange, mm) and the board in the camera (the truth)."""

    name: str
    q_deg: np.ndarray
    q_true_deg: np.ndarray
    T_robot_flange: np.ndarray
    T_camera_board: np.ndarray


def shots(world: World, n: int, seed: int) -> list[Shot]:
    """``n`` poses and what really happened at each."""
    rng = np.random.default_rng(seed + 7919)
    q = sample_poses(world, n, rng)
    out = []
    for i, qi in enumerate(q):
        qt = qi + rng.normal(0.0, world.joint_noise_deg, 6)
        out.append(Shot(str(i), qi, qt, world.nominal.flange(qi), world.T_camera_board(qt)))
    return out


def observe(world: World, shot: Shot, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What a detector reports of one photo: chessboard corner ids, their board points
    (N, 3, sheet frame, mm) and pixels (N, 2) with the detector's noise."""
    X = world.board.corners()
    P = X @ shot.T_camera_board[:3, :3].T + shot.T_camera_board[:3, 3]
    uv = world.lens.project(P) + rng.normal(0.0, world.noise_px, (len(X), 2))
    return np.arange(len(X)), X, uv


def _texture(board: Board, px_per_mm: float) -> tuple[np.ndarray, float]:
    """The board's print (grey, white margin of one square) and its scale (px per mm)."""
    W, H = board.size_mm
    img = board.opencv().generateImage((int(round(W * px_per_mm)), int(round(H * px_per_mm))),
                                       marginSize=0, borderBits=1)
    m = int(round(board.square_mm * px_per_mm))
    return cv2.copyMakeBorder(img, m, m, m, m, cv2.BORDER_CONSTANT, value=255), m


def _normalised_grid(lens: Lens, ws: int, hs: int, s: int, step: int = 8):
    """(nx, ny) (hs, ws) each the undistorted normalised coordinates of every supersampled
    pixel: OpenCV's iterative undistortion on a grid every ``step`` pixels (the distortion
    is smooth), interpolated cubically in between (1e-7 of the normalised plane)."""
    gx = np.arange(0, ws + step, step, dtype=float)
    gy = np.arange(0, hs + step, step, dtype=float)
    gu, gv = np.meshgrid((gx + 0.5) / s - 0.5, (gy + 0.5) / s - 0.5)
    pts = np.c_[gu.ravel(), gv.ravel()].reshape(-1, 1, 2)
    n = cv2.undistortPoints(pts, lens.K, lens.dist, None, None, None,
                            (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12))
    n = n.reshape(len(gy), len(gx), 2)
    xs, ys = np.arange(ws) / step, np.arange(hs) / step
    return tuple(RectBivariateSpline(np.arange(len(gy)), np.arange(len(gx)), n[:, :, k])(
        ys, xs).astype(np.float32) for k in range(2))


def photograph(world: World, T_camera_board: np.ndarray, rng, *, blur_px: float = 0.6,
               noise_grey: float = 2.0, supersample: int = 2) -> np.ndarray:
    """A grey photo (uint8) of the board at ``T_camera_board``: each pixel traced back
    through the lens to the board's plane (supersampled), on a grey background."""
    w, h = world.lens.size_px
    s = supersample
    px_per_mm = 8.0
    tex, margin = _texture(world.board, px_per_mm)
    tex = cv2.GaussianBlur(tex, (0, 0), 0.8)
    nx, ny = _normalised_grid(world.lens, w * s, h * s, s)
    T_bc = _inv(T_camera_board)
    R, o = T_bc[:3, :3].astype(np.float32), T_bc[:3, 3].astype(np.float32)
    # the ray (nx, ny, 1) from the camera's centre o meets the board's plane z = 0
    dz = R[2, 0] * nx + R[2, 1] * ny + R[2, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.float32(-o[2]) / dz
    px = o[0] + lam * (R[0, 0] * nx + R[0, 1] * ny + R[0, 2])
    py = o[1] + lam * (R[1, 0] * nx + R[1, 1] * ny + R[1, 2])
    W, H = world.board.size_mm
    # sheet frame -> texture pixels (y down, origin at the margin's corner)
    f32 = np.float32
    mx = (px + f32(W / 2.0)) * f32(px_per_mm) + f32(margin - 0.5)
    my = (f32(H / 2.0) - py) * f32(px_per_mm) + f32(margin - 0.5)
    bad = ~(lam > 0)
    mx[bad], my[bad] = -1e6, -1e6
    grey = cv2.remap(tex, mx, my, cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=90)
    img = cv2.resize(grey.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)
    img = 20.0 + img * 0.85
    if blur_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur_px)
    img += rng.normal(0.0, noise_grey, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def pose_yaml(T_robot_flange: np.ndarray, joints_deg=None) -> str:
    """A ROS tool's pose file: x y z in metres, the quaternion qx qy qz qw (and the
    commanded joints, deg, when given: ``joints_deg``)."""
    q = [float(v) for v in Rotation.from_matrix(T_robot_flange[:3, :3]).as_quat()]
    t = [float(v) / 1000.0 for v in T_robot_flange[:3, 3]]
    out = (f"x: {t[0]!r}\ny: {t[1]!r}\nz: {t[2]!r}\nqx: {q[0]!r}\nqy: {q[1]!r}\n"
           f"qz: {q[2]!r}\nqw: {q[3]!r}\n")
    if joints_deg is not None:
        out += "joints_deg: [" + ", ".join(repr(float(v)) for v in joints_deg) + "]\n"
    return out


def write_session(folder, world: World, n: int, seed: int, *, render: bool = True,
                  joints: bool = True) -> dict:
    """``folder/images/N.png``, ``folder/poses/N.yaml`` (with the commanded joints unless
    ``joints`` is False) and ``folder/truth.json``; returns the truth (with each photo's
    true board pose)."""
    folder = Path(folder)
    (folder / "images").mkdir(parents=True, exist_ok=True)
    (folder / "poses").mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed + 104729)
    truth = world.truth()
    truth["photos"] = []
    for s in shots(world, n, seed):
        if render:
            cv2.imwrite(str(folder / "images" / f"{s.name}.png"),
                        photograph(world, s.T_camera_board, rng))
        (folder / "poses" / f"{s.name}.yaml").write_text(
            pose_yaml(s.T_robot_flange, s.q_deg if joints else None))
        truth["photos"].append({"file": f"images/{s.name}.png", "q_deg": s.q_deg.tolist(),
                                "q_true_deg": s.q_true_deg.tolist(),
                                "T_camera_board": s.T_camera_board.tolist()})
    (folder / "truth.json").write_text(json.dumps(truth, indent=1))
    return truth


__all__ = ["BOARD", "Board", "Lens", "Shot", "SixAxisArm", "UR5E_DH", "World", "make_world",
           "nominal_arm", "observe", "perturbed_arm", "photograph", "pose_yaml", "random_lens",
           "replace", "sample_poses", "shots", "write_session"]
