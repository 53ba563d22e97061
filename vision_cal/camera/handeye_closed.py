"""The hand-eye's closed form (no OpenCV hand-eye call: OpenCV 5's pip build has none).

Every photo i gives two poses: the flange as the controller reported it, and the board as
the camera saw it (a PnP of its corners). With ``G_i`` the flange pose (camera fixed) or its
inverse (camera on the arm) and ``C_i`` the board in the camera, the two unknowns ``Y`` (the
board on the flange, or in the robot frame) and ``X`` (the camera in the robot frame, or
on the flange) satisfy ``G_i Y = X C_i`` for every photo: the AX = ZB problem
(:func:`solve_axzb`, ``A_i = G_i``, ``B_i = C_i``).

The rotations come first, linearly: ``R_A R_X = R_Z R_B`` is ``(I kron R_A) vec R_X -
(R_B^T kron I) vec R_Z = 0``, 9 equations a photo in 18 unknowns; the null vector of the
stacked system (its smallest right singular vector), split and scaled to determinant 1,
projected onto the rotations (Shah 2013, "Solving the robot-world/hand-eye calibration
problem using the Kronecker product"). Then the translations, linearly, from ``R_A t_X -
t_Z = R_Z t_B - t_A``; with the robot's translations scaled by an unknown ``s`` as well
(``solve_axzb(..., free_scale=True)``), which is 1 when the poses and the board are in the same unit, 1000
when the poses are in metres read as millimetres, 25.4 for inches, and the board's size
off by 1/s when its squares are misdeclared. Each is one SVD and one least squares:
microseconds, no start needed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation


def nearest_rotation(M: np.ndarray) -> np.ndarray:
    """The rotation nearest ``M`` (3, 3) in the Frobenius norm (SVD, det +1)."""
    U, _, Vt = np.linalg.svd(M)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


def inv_T(T: np.ndarray) -> np.ndarray:
    """The inverse of rigid transforms (..., 4, 4)."""
    T = np.asarray(T, float)
    R = T[..., :3, :3]
    t = T[..., :3, 3]
    out = np.zeros_like(T)
    Rt = np.swapaxes(R, -1, -2)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, t)
    out[..., 3, 3] = 1.0
    return out


def angle_deg(R: np.ndarray) -> np.ndarray:
    """The rotation angle (deg) of rotations (..., 3, 3)."""
    tr = np.trace(R, axis1=-2, axis2=-1)
    return np.degrees(np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0)))


@dataclass(frozen=True)
class AxzbSolution:
    """``A_i X = Z B_i`` solved: ``X``, ``Z`` (4, 4), each photo's rotation disagreement
    (deg) and translation disagreement (mm) at the solution, and the robot scale ``s``
    used (1 unless asked to estimate it)."""

    X: np.ndarray
    Z: np.ndarray
    rotation_deg: np.ndarray
    translation_mm: np.ndarray
    scale: float = 1.0

    @property
    def rotation_rms_deg(self) -> float:
        return float(np.sqrt(np.mean(self.rotation_deg ** 2)))

    @property
    def translation_rms_mm(self) -> float:
        return float(np.sqrt(np.mean(self.translation_mm ** 2)))


def _rotations(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R_X, R_Z from the Kronecker null vector."""
    I3 = np.eye(3)
    rows = [np.hstack([np.kron(I3, a[:3, :3]), -np.kron(b[:3, :3].T, I3)])
            for a, b in zip(A, B)]
    _, _, Vt = np.linalg.svd(np.vstack(rows))
    v = Vt[-1]
    RX = v[:9].reshape(3, 3, order="F")
    RZ = v[9:].reshape(3, 3, order="F")
    d = np.linalg.det(RX)
    s = np.sign(d) * abs(d) ** (1.0 / 3.0) if d != 0 else 1.0
    return nearest_rotation(RX / s), nearest_rotation(RZ / s)


def _translations(A, B, RZ, *, free_scale: bool) -> tuple[np.ndarray, np.ndarray, float]:
    """t_X, t_Z (and the robot scale s when ``free_scale``) by linear least squares."""
    I3 = np.eye(3)
    M, rhs = [], []
    for a, b in zip(A, B):
        row = [a[:3, :3], -I3]
        if free_scale:
            row.append(a[:3, 3:4])
            rhs.append(RZ @ b[:3, 3])
        else:
            rhs.append(RZ @ b[:3, 3] - a[:3, 3])
        M.append(np.hstack(row))
    sol = np.linalg.lstsq(np.vstack(M), np.concatenate(rhs), rcond=None)[0]
    return sol[:3], sol[3:6], float(sol[6]) if free_scale else 1.0


def solve_axzb(A, B, *, free_scale: bool = False) -> AxzbSolution:
    """``A_i X = Z B_i`` for rigid transforms ``A``, ``B`` (N, 4, 4), N >= 3 with the
    ``A`` rotations about at least two different axes (else a direction is not fixed: the
    caller checks the motion). ``free_scale``: ``A``'s translations scaled by an unknown
    factor, estimated (see the module docstring)."""
    A = np.asarray(A, float)
    B = np.asarray(B, float)
    RX, RZ = _rotations(A, B)
    tX, tZ, s = _translations(A, B, RZ, free_scale=free_scale)
    X = np.eye(4)
    X[:3, :3], X[:3, 3] = RX, tX
    Z = np.eye(4)
    Z[:3, :3], Z[:3, 3] = RZ, tZ
    As = A.copy()
    As[:, :3, 3] *= s
    L = As @ X
    Rr = Z @ B
    rot = angle_deg(np.swapaxes(L[:, :3, :3], -1, -2) @ Rr[:, :3, :3])
    tr = np.linalg.norm(L[:, :3, 3] - Rr[:, :3, 3], axis=1)
    return AxzbSolution(X, Z, rot, tr, s)


def rotation_spread_deg(A) -> float:
    """The largest angle (deg) between any two of the rotations ``A`` (N, 4, 4): the
    robot must turn between photos for the hand-eye to be seen at all."""
    R = np.asarray(A, float)[:, :3, :3]
    rel = np.einsum("iba,jbc->ijac", R, R)
    return float(angle_deg(rel).max()) if len(R) > 1 else 0.0


def axis_spread(A) -> float:
    """How far the relative rotations between photos are from sharing one axis: the second
    singular value of their (angle-weighted) axes, in degrees (0: all about one axis, a
    direction of the hand-eye unseen)."""
    R = np.asarray(A, float)[:, :3, :3]
    v = []
    for i in range(len(R)):
        for j in range(i + 1, len(R)):
            v.append(Rotation.from_matrix(R[i].T @ R[j]).as_rotvec())
    if len(v) < 2:
        return 0.0
    s = np.linalg.svd(np.degrees(np.array(v)), compute_uv=False)
    return float(s[1] / np.sqrt(len(v)))
