"""The hand-eye's one least squares: every board corner of every photo predicted from the
robot's pose and the unknowns, against where the camera saw it.

A photo i's board sits in the camera at ``T_camera_board = X^-1 G_i Y``: camera fixed,
``G_i = T_robot_flange_i``, ``X = T_robot_camera``, ``Y = T_flange_board``; camera on the arm,
``G_i = T_robot_flange_i^-1``, ``X = T_flange_camera``, ``Y = T_robot_board``. The board's
corners (board frame, mm) go through it and the lens (OpenCV's pinhole with ``k1 k2 p1 p2
k3``, :func:`project`) to pixels. The unknowns: ``X`` and ``Y`` (each a rotation about its
parent frame's axes and a translation, mm, around the closed-form start) and the lens
terms that are not declared. Optionally each photo's flange is let off the controller's
report by a small rigid error ``D_i`` (``T_robot_flange_i D_i``) held to the robot's pose
error by a prior (``pose_sigma``: rotation deg, translation mm per axis): the photos'
own parameters, which make the Jacobian sparse (``jac_sparsity``: a corner depends on the
shared unknowns and its own photo's six).

Residuals are in units of the corner noise (``sigma_px``); the solve is the one solver
(:func:`vision_cal.model.solve.solve`: a solve stopped on its evaluation limit is refused)
and the result's ``cov`` the covariance of the shared unknowns by the one policy
(:func:`vision_cal.model.solve.covariance`, ``s^2 = 1``: the prior's parameters
marginalised, a direction the photos do not fix with an infinite variance), in the order of
:attr:`Refined.labels`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix, hstack
from scipy.spatial.transform import Rotation

from vision_cal.camera.handeye_closed import inv_T
from vision_cal.errors import VisionCalError
from vision_cal.model.solve import covariance, solve

#: the lens terms, in the order of the lens vector
LENS_NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
#: the pose parameters of X and Y (rotation about the parent frame's axes, translation)
POSE_NAMES = ("rot_x_deg", "rot_y_deg", "rot_z_deg", "x_mm", "y_mm", "z_mm")
MOUNTS = ("fixed", "arm")


def lens_vector(K: np.ndarray, dist) -> np.ndarray:
    """(9,) fx fy cx cy k1 k2 p1 p2 k3 of an OpenCV ``K`` and ``dist`` (4-5 terms used; a
    longer model is refused by the caller)."""
    d = np.zeros(5)
    dist = np.asarray(dist, float).ravel()
    d[:min(5, len(dist))] = dist[:5]
    return np.r_[K[0, 0], K[1, 1], K[0, 2], K[1, 2], d]


def lens_K(v: np.ndarray) -> np.ndarray:
    return np.array([[v[0], 0.0, v[2]], [0.0, v[1], v[3]], [0.0, 0.0, 1.0]])


def project(P: np.ndarray, lens: np.ndarray) -> np.ndarray:
    """Camera-frame points (N, 3) -> pixels (N, 2) through ``lens`` (9,)."""
    fx, fy, cx, cy, k1, k2, p1, p2, k3 = lens
    x, y = P[:, 0] / P[:, 2], P[:, 1] / P[:, 2]
    r2 = x * x + y * y
    rad = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * rad + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * rad + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return np.c_[fx * xd + cx, fy * yd + cy]


def project_jacobian(P: np.ndarray, lens: np.ndarray):
    """Pixels (N, 2), their derivatives by the camera-frame point (N, 2, 3) and by the lens
    (N, 2, 9) (:func:`project`'s model)."""
    fx, fy, cx, cy, k1, k2, p1, p2, k3 = lens
    iz = 1.0 / P[:, 2]
    x, y = P[:, 0] * iz, P[:, 1] * iz
    r2 = x * x + y * y
    rad = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    drad = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)          # d rad / d r2
    xd = x * rad + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * rad + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    dxd = np.stack([rad + 2 * x * x * drad + 2 * p1 * y + 6 * p2 * x,
                    2 * x * y * drad + 2 * p1 * x + 2 * p2 * y], axis=-1)   # d xd / d(x, y)
    dyd = np.stack([2 * x * y * drad + 2 * p1 * x + 2 * p2 * y,
                    rad + 2 * y * y * drad + 6 * p1 * y + 2 * p2 * x], axis=-1)
    dxy = np.zeros((len(P), 2, 3))                          # d(x, y) / dP
    dxy[:, 0, 0] = iz
    dxy[:, 0, 2] = -x * iz
    dxy[:, 1, 1] = iz
    dxy[:, 1, 2] = -y * iz
    dP = np.empty((len(P), 2, 3))
    dP[:, 0] = fx * np.einsum("nk,nkj->nj", dxd, dxy)
    dP[:, 1] = fy * np.einsum("nk,nkj->nj", dyd, dxy)
    dL = np.zeros((len(P), 2, 9))
    dL[:, 0, 0], dL[:, 1, 1], dL[:, 0, 2], dL[:, 1, 3] = xd, yd, 1.0, 1.0
    for k, pw in ((4, r2), (5, r2 * r2), (8, r2 ** 3)):
        dL[:, 0, k], dL[:, 1, k] = fx * x * pw, fy * y * pw
    dL[:, 0, 6], dL[:, 1, 6] = fx * 2 * x * y, fy * (r2 + 2 * y * y)
    dL[:, 0, 7], dL[:, 1, 7] = fx * (r2 + 2 * x * x), fy * 2 * x * y
    return np.c_[fx * xd + cx, fy * yd + cy], dP, dL


def _skew(v: np.ndarray) -> np.ndarray:
    """(N, 3, 3) cross-product matrices of rows ``v`` (N, 3)."""
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def compose(T0: np.ndarray, d: np.ndarray) -> np.ndarray:
    """``T0`` turned by rotation vector ``d[:3]`` (deg, about its parent frame's axes) and
    moved by ``d[3:6]`` (mm)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.radians(d[:3])).as_matrix() @ T0[:3, :3]
    T[:3, 3] = T0[:3, 3] + d[3:6]
    return T


def _small_T(d: np.ndarray) -> np.ndarray:
    """(n, 4, 4) rigid transforms of rows ``d`` (n, 6): rotation vector deg, translation mm."""
    T = np.tile(np.eye(4), (len(d), 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec(np.radians(d[:, :3])).as_matrix()
    T[:, :3, 3] = d[:, 3:6]
    return T


@dataclass(frozen=True)
class View:
    """One photo: its name, the flange pose the controller reported (4, 4, mm), and the
    board's points seen: ``ids`` (N,), ``board_mm`` (N, 3) in the board's frame, ``px``
    (N, 2) where the camera saw them; the arm's joints (deg) when the poses give them."""

    name: str
    T_robot_flange: np.ndarray
    ids: np.ndarray
    board_mm: np.ndarray
    px: np.ndarray
    joints_deg: np.ndarray | None = None


@dataclass(frozen=True)
class Refined:
    """The least squares' solution: ``X``, ``Y`` (4, 4), ``lens`` (9,), ``free`` (9,) bool
    (the lens terms fitted), each photo's pose error ``D`` (n, 6) (zeros without a prior),
    the residual ``residual_px`` (N, 2) with ``view_of`` (N,) its photo index, ``cov``
    (P, P) of ``labels`` (X's six, Y's six, the free lens terms), ``cost`` (half the sum
    of squared normalised residuals) and ``dof``."""

    X: np.ndarray
    Y: np.ndarray
    lens: np.ndarray
    free: np.ndarray
    D: np.ndarray
    residual_px: np.ndarray
    view_of: np.ndarray
    cov: np.ndarray
    labels: tuple[str, ...]
    cost: float
    dof: int

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov), 0.0, None))


class Problem:
    """The least squares of a set of views (see the module docstring)."""

    def __init__(self, views, mount: str, X0, Y0, lens0, free, *, sigma_px: float = 1.0,
                 pose_sigma: tuple[float, float] | None = None):
        if mount not in MOUNTS:
            raise ValueError(f"mount {mount!r}")
        self.views = list(views)
        self.mount = mount
        self.X0, self.Y0 = np.asarray(X0, float), np.asarray(Y0, float)
        self.lens0 = np.asarray(lens0, float)
        self.free = np.asarray(free, bool)
        self.sigma_px = float(sigma_px)
        self.pose_sigma = pose_sigma
        self.F = np.array([v.T_robot_flange for v in self.views], float)
        self.pts = np.vstack([v.board_mm for v in self.views])
        self.px = np.vstack([v.px for v in self.views])
        self.view_of = np.concatenate([np.full(len(v.px), i) for i, v in enumerate(self.views)])
        self.n_shared = 12 + int(self.free.sum())
        n_pose = 6 * len(self.views) if pose_sigma is not None else 0
        self.n_params = self.n_shared + n_pose

    def unpack(self, p: np.ndarray):
        X = compose(self.X0, p[:6])
        Y = compose(self.Y0, p[6:12])
        lens = self.lens0.copy()
        lens[self.free] = p[12:self.n_shared]
        D = (p[self.n_shared:].reshape(-1, 6) if self.pose_sigma is not None
             else np.zeros((len(self.views), 6)))
        return X, Y, lens, D

    def start(self) -> np.ndarray:
        return np.r_[np.zeros(12), self.lens0[self.free],
                     np.zeros(self.n_params - self.n_shared)]

    def _chain(self, p: np.ndarray):
        """Every point through the chain: the board point on its mount ``q`` (in the
        flange frame, camera fixed; in the robot frame, on the arm), in the frame of ``X``'s
        parent ``W``, in the camera ``P``; and the pieces the derivatives need."""
        X, Y, lens, D = self.unpack(p)
        F = self.F @ _small_T(D) if self.pose_sigma is not None else self.F
        G = (F if self.mount == "fixed" else inv_T(F))[self.view_of]
        Ry_p = self.pts @ Y[:3, :3].T
        q = Ry_p + Y[:3, 3]
        W = np.einsum("nij,nj->ni", G[:, :3, :3], q) + G[:, :3, 3]
        P = (W - X[:3, 3]) @ X[:3, :3]
        return X, lens, G, Ry_p, q, W, P

    def predict(self, p: np.ndarray) -> np.ndarray:
        """(N, 2) pixels predicted for every point of every view."""
        *_, lens, _, _, _, _, P = (None,) + self._chain(p)
        return project(P, lens)

    def jacobians(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(2N, n_shared) d pixels / d shared unknowns and (2N, 6) d pixels / d the photo's
        own flange error (rotation deg, translation mm; each row for its own photo's),
        analytic."""
        X, lens, G, Ry_p, q, W, P = self._chain(p)
        _, dP, dL = project_jacobian(P, lens)
        RxT = X[:3, :3].T
        deg = np.pi / 180.0
        dPdw = np.empty((len(P), 3, 12))
        dPdw[:, :, 0:3] = np.einsum("ij,njk->nik", RxT, _skew(W - X[:3, 3])) * deg
        dPdw[:, :, 3:6] = -RxT
        RG = np.einsum("ij,njk->nik", RxT, G[:, :3, :3])
        dPdw[:, :, 6:9] = -np.einsum("nij,njk->nik", RG, _skew(Ry_p)) * deg
        dPdw[:, :, 9:12] = RG
        Js = np.concatenate([np.einsum("nij,njk->nik", dP, dPdw),
                             dL[:, :, self.free]], axis=2).reshape(-1, self.n_shared)
        # the flange's own error D (T_robot_flange D): fixed W = F (D q); arm W = D^-1 (F^-1 q)
        dW = np.empty((len(P), 3, 6))
        if self.mount == "fixed":
            Rf = G[:, :3, :3]
            dW[:, :, 0:3] = -np.einsum("nij,njk->nik", Rf, _skew(q)) * deg
            dW[:, :, 3:6] = Rf
        else:
            dW[:, :, 0:3] = _skew(W) * deg
            dW[:, :, 3:6] = -np.eye(3)
        Jd = np.einsum("nij,njk->nik", dP, np.einsum("ij,njk->nik", RxT, dW)).reshape(-1, 6)
        return Js, Jd

    def residual(self, p: np.ndarray) -> np.ndarray:
        r = ((self.predict(p) - self.px) / self.sigma_px).ravel()
        if self.pose_sigma is None:
            return r
        sr, st = self.pose_sigma
        D = p[self.n_shared:].reshape(-1, 6)
        return np.r_[r, (D / np.array([sr] * 3 + [st] * 3)).ravel()]

    def jac(self, p: np.ndarray):
        """The residual's Jacobian: dense without pose errors, sparse (CSR) with them."""
        Js, Jd = self.jacobians(p)
        if self.pose_sigma is None:
            return Js / self.sigma_px
        n2 = len(Js)
        rows = np.repeat(np.arange(n2), 6)
        cols = (self.n_shared + 6 * np.repeat(self.view_of, 2)[:, None]
                + np.arange(6)).ravel()
        sr, st = self.pose_sigma
        prior = 1.0 / np.array([sr] * 3 + [st] * 3)
        nv = len(self.views)
        J = csr_matrix((np.r_[Jd.ravel() / self.sigma_px, np.tile(prior, nv)],
                        (np.r_[rows, n2 + np.arange(6 * nv)],
                         np.r_[cols, self.n_shared + np.arange(6 * nv)])),
                       shape=(n2 + 6 * nv, self.n_params))
        return hstack([csr_matrix(np.r_[Js / self.sigma_px, np.zeros((6 * nv, self.n_shared))]),
                       J[:, self.n_shared:]]).tocsr()

    def x_scale(self) -> np.ndarray:
        """Typical steps: 0.1 deg, 1 mm, 1 px for K, 0.01 for distortion."""
        lens_scale = np.array([10.0, 10.0, 10.0, 10.0, 0.01, 0.01, 0.001, 0.001, 0.01])
        pose = [] if self.pose_sigma is None else list(
            np.tile([self.pose_sigma[0]] * 3 + [self.pose_sigma[1]] * 3, len(self.views)))
        return np.r_[[0.1] * 3, [1.0] * 3, [0.1] * 3, [1.0] * 3, lens_scale[self.free], pose]


def refine(problem: Problem, p0: np.ndarray | None = None, *, max_nfev: int = 100) -> Refined:
    """Solve ``problem`` (a trust-region least squares with the analytic Jacobian, sparse
    when the photos have their own pose errors) and the covariance of the shared unknowns
    (the pose errors marginalised)."""
    p0 = problem.start() if p0 is None else p0
    sparse = problem.pose_sigma is not None
    r = solve(problem.residual, p0, jac=problem.jac, method="trf",
              tr_solver="lsmr" if sparse else "exact", x_scale=problem.x_scale(),
              max_nfev=max_nfev, xtol=1e-10, ftol=1e-10)
    if not r:
        raise VisionCalError(f"the hand-eye's least squares: {r.reason}")
    J = problem.jac(r.x)
    J = J.toarray() if sparse else J
    ns = problem.n_shared
    X, Y, lens, D = problem.unpack(r.x)
    resid = problem.predict(r.x) - problem.px
    n_obs = 2 * len(problem.px)
    labels = (tuple(f"X.{n}" for n in POSE_NAMES) + tuple(f"Y.{n}" for n in POSE_NAMES)
              + tuple(f"lens.{n}" for n, f in zip(LENS_NAMES, problem.free) if f))
    cov_all = covariance(J, labels=labels + tuple(f"D.{i}" for i in range(J.shape[1] - ns)))
    return Refined(X, Y, lens, problem.free.copy(), D, resid, problem.view_of,
                   cov_all.stated[:ns, :ns], labels, r.cost, n_obs - ns)
