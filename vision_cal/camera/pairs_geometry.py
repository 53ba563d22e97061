"""The geometry of SCARA pose pairs (``vision-cal handeye --poses``): the 4-DOF closed form
and where a pair puts the target, in arrays whose cost is linear in the pairs.

``A`` (N, 4, 4) are the moving transforms ``A'_i`` (``T_robot_flange`` for a camera on the
arm, its inverse for a fixed one), ``B`` (N, 4, 4) the target as the camera saw it; the two
unknowns close ``A'_i X B_i = Y`` (:mod:`vision_cal.camera.pose_pairs`' docstring).

The closed form (Ulrich & Steger's idea for SCARA hand-eye): ``g = R_Y^T z`` and
``h = R_X^T z`` satisfy ``R_B_i g = h`` in every pair, the null vector of the stacked
``[R_B_i, -I]`` (up to a sign, tried both ways); with ``R_X = Rz(a) R_h`` the angle ``a``
comes from the x, y rows of the translations, linear in ``(t_X,x, t_X,y, s cos a, s sin a,
t_Y,x, t_Y,y)``. ``s`` is the scale of the target's translations against the flange's: 1
for pairs in one unit; the fit holds it at 1, and :func:`closed_form_parts` reports it with
its std so that a file whose flange and target are in different units is told apart
(:mod:`vision_cal.camera.pairs_checks`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from vision_cal.model.solve import covariance


def rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def T_of(R, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def project_so3(M: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(M)
    R = U @ Vt
    if np.linalg.det(R) < 0:
        U[:, -1] *= -1
        R = U @ Vt
    return R


def onto_z(h: np.ndarray) -> np.ndarray:
    """The smallest rotation turning unit ``h`` onto z."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(h, z)
    s, c = np.linalg.norm(axis), float(np.dot(h, z))
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = axis / s
    Kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + s * Kx + (1.0 - c) * Kx @ Kx          # Rodrigues: sin = s, cos = c


def rotmat(v) -> np.ndarray:
    """(3, 3) rotation of the rotation vector ``v`` (rad; Rodrigues' formula: scipy's
    conversion costs ten times as much, and the fit unpacks its parameters thousands of
    times)."""
    v = np.asarray(v, float)
    a = math.sqrt(float(v @ v))
    if a < 1e-12:
        return np.eye(3) + np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    k = v / a
    Kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(a) * Kx + (1.0 - math.cos(a)) * (Kx @ Kx)


def rotvec(R: np.ndarray) -> np.ndarray:
    """(N, 3) rotation vectors (rad) of rotations (N, 3, 3): the angle from both the trace
    and the skew part (exact at small angles), scipy's conversion near a half turn only
    (it costs ten times as much: the fit evaluates this for every pair many times)."""
    v = 0.5 * np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0],
                        R[:, 1, 0] - R[:, 0, 1]], axis=1)            # sin(angle) axis
    s = np.linalg.norm(v, axis=1)
    angle = np.arctan2(s, 0.5 * (np.trace(R, axis1=1, axis2=2) - 1.0))
    f = np.where(s > 1e-12, angle / np.where(s > 1e-12, s, 1.0), 1.0)
    out = v * f[:, None]
    near = angle > 3.0
    if near.any():
        out[near] = Rotation.from_matrix(R[near]).as_rotvec()
    return out


def yaw_deg(A: np.ndarray) -> np.ndarray:
    """(N,) each transform's turn about z (deg)."""
    return np.degrees(np.arctan2(A[:, 1, 0], A[:, 0, 0]))


def yaw_spread_deg(A: np.ndarray) -> float:
    """The largest turn about z between the first transform and any other (deg)."""
    y = np.radians(yaw_deg(A))
    return float(np.degrees(np.abs(np.angle(np.exp(1j * (y - y[0]))))).max())


@dataclass(frozen=True)
class ClosedForm:
    """The 4-DOF start: ``X``, ``Y`` (4, 4); ``scale`` the target translations' scale
    against the flange's that the pairs ask for (1: one unit) and ``scale_std`` its std
    from the linear rows' scatter (inf: the motion does not fix it)."""

    X: np.ndarray
    Y: np.ndarray
    scale: float
    scale_std: float


def _linear_rows(A: np.ndarray, B: np.ndarray, Rh: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The x, y rows (2N, 6) and right side (2N,) of the translations, linear in
    ``(t_X,x, t_X,y, s cos a, s sin a, t_Y,x, t_Y,y)``."""
    n = len(A)
    Rz2 = A[:, :2, :2]                                   # (N, 2, 2)
    w = B[:, :3, 3] @ Rh.T                               # (N, 3): R_h t_B
    V = np.zeros((n, 2, 2))
    V[:, 0, 0], V[:, 0, 1], V[:, 1, 0], V[:, 1, 1] = w[:, 0], -w[:, 1], w[:, 1], w[:, 0]
    G = np.concatenate([Rz2, np.einsum("nij,njk->nik", Rz2, V),
                        np.broadcast_to(-np.eye(2), (n, 2, 2))], axis=2)
    return G.reshape(2 * n, 6), -A[:, :2, 3].reshape(2 * n)


def _scale_std(G: np.ndarray, rhs: np.ndarray, u: np.ndarray) -> float:
    """The std of ``|u[2:4]|`` from the rows' scatter (inf: not fixed by them)."""
    dof = len(rhs) - 6
    s = np.linalg.svd(G, compute_uv=False)
    if dof <= 0 or s[-1] < 1e-9 * max(s[0], 1e-300):
        return float("inf")
    r = G @ u - rhs
    cov = covariance(G, s2=float(r @ r) / dof).matrix
    d = u[2:4] / max(float(np.hypot(u[2], u[3])), 1e-300)
    return float(np.sqrt(max(d @ cov[2:4, 2:4] @ d, 0.0)))


def closed_form_parts(A: np.ndarray, B: np.ndarray, z_mm: float = 0.0, *,
                      with_std: bool = True) -> ClosedForm:
    """The 4-DOF start (module docstring) from ``A'`` and ``B`` (N, 4, 4), ``Y``'s origin
    at height ``z_mm``; of the two signs of the robot's z, the one whose pairs agree best
    (``with_std`` False: the scale's std is not computed, NaN)."""
    n = len(A)
    M = np.zeros((3 * n, 6))
    M[:, :3] = B[:, :3, :3].reshape(3 * n, 3)
    M[:, 3:] = np.tile(-np.eye(3), (n, 1))
    v = np.linalg.svd(M, full_matrices=False)[2][-1]
    best = None
    for sign in (1.0, -1.0):
        h = sign * v[3:] / np.linalg.norm(v[3:])
        Rh = onto_z(h)
        D = project_so3(np.einsum("nij,jk,nkl->il", A[:, :3, :3], Rh, B[:, :3, :3]))
        G, rhs = _linear_rows(A, B, Rh)
        u = np.linalg.lstsq(G, rhs, rcond=None)[0]
        a = math.atan2(u[3], u[2])
        RX = rz(a) @ Rh
        RY = rz(a) @ D
        dz = float(np.mean(-A[:, 2, 3] - B[:, :3, 3] @ RX[2]))
        X = T_of(RX, [u[0], u[1], z_mm + dz])
        Y = T_of(RY, [u[4], u[5], z_mm])
        P = A @ X @ B
        cost = float(np.sum((P[:, :3, 3] - Y[:3, 3]) ** 2))
        if best is None or cost < best[0]:
            best = (cost, X, Y, float(np.hypot(u[2], u[3])), G, rhs, u)
    _, X, Y, scale, G, rhs, u = best
    return ClosedForm(X, Y, scale, _scale_std(G, rhs, u) if with_std else float("nan"))


def closed_form(A: np.ndarray, B: np.ndarray, z_mm: float = 0.0
                ) -> tuple[np.ndarray, np.ndarray]:
    """(X, Y) of :func:`closed_form_parts`."""
    c = closed_form_parts(A, B, z_mm, with_std=False)
    return c.X, c.Y


def _onto_z_many(h: np.ndarray) -> np.ndarray:
    """(T, 3, 3) :func:`onto_z` of unit vectors ``h`` (T, 3)."""
    axis = np.stack([h[:, 1], -h[:, 0], np.zeros(len(h))], axis=1)        # h x z
    s = np.linalg.norm(axis, axis=1)
    c = h[:, 2]
    k = axis / np.where(s > 1e-12, s, 1.0)[:, None]
    Kx = np.zeros((len(h), 3, 3))
    Kx[:, 0, 1], Kx[:, 0, 2], Kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    Kx[:, 1, 0], Kx[:, 2, 0], Kx[:, 2, 1] = k[:, 2], -k[:, 1], k[:, 0]
    R = np.eye(3) + s[:, None, None] * Kx + (1.0 - c)[:, None, None] * Kx @ Kx
    down = (s <= 1e-12) & (c < 0)
    R[down] = np.diag([1.0, -1.0, -1.0])
    return R


def closed_form_many(A: np.ndarray, B: np.ndarray, z_mm: float = 0.0
                     ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`closed_form` of many small sets at once: ``A``, ``B`` (T, k, 4, 4) give
    ``X``, ``Y`` (T, 4, 4) (the consensus's random triples; a set whose rows do not fix
    the translations gets the least-norm solution)."""
    t, k = A.shape[:2]
    M = np.zeros((t, 3 * k, 6))
    M[:, :, :3] = B[:, :, :3, :3].reshape(t, 3 * k, 3)
    M[:, :, 3:] = np.tile(-np.eye(3), (k, 1))
    v = np.linalg.svd(M)[2][:, -1]
    best_cost = np.full(t, np.inf)
    X, Y = np.tile(np.eye(4), (t, 1, 1)), np.tile(np.eye(4), (t, 1, 1))
    for sign in (1.0, -1.0):
        h = sign * v[:, 3:] / np.linalg.norm(v[:, 3:], axis=1)[:, None]
        Rh = _onto_z_many(h)
        U, _, Vt = np.linalg.svd(np.einsum("tnij,tjk,tnkl->til", A[..., :3, :3], Rh,
                                           B[..., :3, :3]))
        U[np.linalg.det(U @ Vt) < 0, :, -1] *= -1
        D = U @ Vt
        Rz2 = A[..., :2, :2]                                        # (T, k, 2, 2)
        w = np.einsum("tij,tnj->tni", Rh, B[..., :3, 3])
        V = np.zeros((t, k, 2, 2))
        V[..., 0, 0], V[..., 0, 1], V[..., 1, 0], V[..., 1, 1] = (w[..., 0], -w[..., 1],
                                                                  w[..., 1], w[..., 0])
        G = np.concatenate([Rz2, Rz2 @ V, np.broadcast_to(-np.eye(2), (t, k, 2, 2))], axis=3)
        G = G.reshape(t, 2 * k, 6)
        u = (np.linalg.pinv(G) @ -A[..., :2, 3].reshape(t, 2 * k, 1))[..., 0]
        a = np.arctan2(u[:, 3], u[:, 2])
        Rza = np.zeros((t, 3, 3))
        Rza[:, 0, 0], Rza[:, 0, 1], Rza[:, 1, 0], Rza[:, 1, 1], Rza[:, 2, 2] = (
            np.cos(a), -np.sin(a), np.sin(a), np.cos(a), 1.0)
        RX, RY = Rza @ Rh, Rza @ D
        dz = np.mean(-A[..., 2, 3] - np.einsum("tj,tnj->tn", RX[:, 2], B[..., :3, 3]), axis=1)
        Xs, Ys = np.tile(np.eye(4), (t, 1, 1)), np.tile(np.eye(4), (t, 1, 1))
        Xs[:, :3, :3], Xs[:, :2, 3], Xs[:, 2, 3] = RX, u[:, :2], z_mm + dz
        Ys[:, :3, :3], Ys[:, :2, 3], Ys[:, 2, 3] = RY, u[:, 4:6], z_mm
        P = A @ Xs[:, None] @ B
        cost = np.sum((P[..., :3, 3] - Ys[:, None, :3, 3]) ** 2, axis=(1, 2))
        better = cost < best_cost
        X[better], Y[better], best_cost[better] = Xs[better], Ys[better], cost[better]
    return X, Y


def target_points(B: np.ndarray) -> np.ndarray:
    """(5, 3) points in the target's frame that weigh a pair's rotation against its
    translation: its origin and four points half the median camera distance from it
    (a turn of the target moves them as the camera would see it move a board that size)."""
    d = 0.5 * float(np.median(np.linalg.norm(B[:, :3, 3], axis=1)))
    return np.array([[0, 0, 0], [d, 0, 0], [-d, 0, 0], [0, d, 0], [0, -d, 0]], float)


def spread_mm(A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray,
              pts: np.ndarray) -> np.ndarray:
    """(N,) how far each pair puts the target's ``pts`` from where ``Y`` has them: the RMS
    over the points (mm). ``X``, ``Y`` (T, 4, 4) give (T, N), one row a candidate."""
    if X.ndim == 3:
        return np.stack([spread_mm(A, B, x, y, pts) for x, y in zip(X, Y)])
    P = A @ X @ B
    D = P[:, :3, :3] - Y[:3, :3]                                     # (N, 3, 3)
    d = (D @ pts.T).transpose(0, 2, 1) + (P[:, :3, 3] - Y[:3, 3])[:, None, :]
    return np.sqrt(np.mean(np.sum(d**2, axis=2), axis=1))
