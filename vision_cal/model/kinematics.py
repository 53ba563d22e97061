"""Base kinematic model of a 2-link SCARA in the sheet frame.

Conventions (``docs/conventions.md``)::

    phi1 = q1 + z1              phi2 = q2 + z2
    pen  = base + L1 [cos phi1, sin phi1] + L2 [cos(phi1+phi2), sin(phi1+phi2)]

Angles are degrees at the API (as in every file) and radians inside.

Only planar marks are seen, so the rotation of the robot base about its vertical
axis and the joint-1 zero offset are **one parameter**: ``z1`` is the angle of link 1
at commanded zero measured from the sheet x axis, and it absorbs both.

The flat parameter vector (``ScaraParams.vector``) is, in internal units::

    [L1_mm, L2_mm, z1_rad, z2_rad, base_x_mm, base_y_mm]

Joint 4 and the tool (contract section "Joint 4 and the tool", docs/format.md): with the
pen at ``tool`` (mm) in the flange frame at commanded ``q4 = 0``::

    pen = base + L1 [cos phi1, sin phi1] + L2 [cos(phi1+phi2), sin(phi1+phi2)]
               + Rot(phi1 + phi2 + q4) tool

:func:`tool_offset_rad` is that last term; :func:`flange_angle_rad` is ``phi1 + phi2``
(the direction of link 2, the flange frame's x axis at ``q4 = 0``). Every function here
without a tool is the tool-less model (tool = [0, 0], q4 = 0).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vision_cal.errors import VisionCalError


@dataclass(frozen=True)
class ScaraParams:
    """Parameters of the base model (mm and degrees)."""

    L1_mm: float
    L2_mm: float
    z1_deg: float = 0.0
    z2_deg: float = 0.0
    base_x_mm: float = 0.0
    base_y_mm: float = 0.0

    @property
    def joint_zero_deg(self) -> tuple[float, float]:
        return (self.z1_deg, self.z2_deg)

    @property
    def base_mm(self) -> tuple[float, float]:
        return (self.base_x_mm, self.base_y_mm)

    @property
    def vector(self) -> np.ndarray:
        """Flat view in internal units: (6,) [mm, mm, rad, rad, mm, mm]."""
        return np.array(
            [self.L1_mm, self.L2_mm, np.radians(self.z1_deg), np.radians(self.z2_deg),
             self.base_x_mm, self.base_y_mm], dtype=float)

    @classmethod
    def from_vector(cls, v: np.ndarray) -> "ScaraParams":
        v = np.asarray(v, dtype=float)
        return cls(float(v[0]), float(v[1]), float(np.degrees(v[2])), float(np.degrees(v[3])),
                   float(v[4]), float(v[5]))

    def to_json(self) -> dict:
        """The ``params`` block of calibration.json / truth.json."""
        return {"L1_mm": self.L1_mm, "L2_mm": self.L2_mm,
                "joint_zero_deg": [self.z1_deg, self.z2_deg],
                "base_mm": [self.base_x_mm, self.base_y_mm]}

    @classmethod
    def from_json(cls, d: dict) -> "ScaraParams":
        return cls(float(d["L1_mm"]), float(d["L2_mm"]), float(d["joint_zero_deg"][0]),
                   float(d["joint_zero_deg"][1]), float(d["base_mm"][0]), float(d["base_mm"][1]))


#: the base vector's entries (:attr:`ScaraParams.vector`; a model's labels begin so)
BASE_LABELS = ("L1_mm", "L2_mm", "z1", "z2", "base_x_mm", "base_y_mm")


@dataclass(frozen=True)
class ParamMask:
    """Which of the six base parameters are free in a fit (pybotics style), by the labels of
    :data:`BASE_LABELS`; a model's effects are held (:meth:`over`)::

        placement = ParamMask.of("z1", "base_x_mm", "base_y_mm")
        solve(residual, model.vector, jac=jac, free=placement.over(len(model.vector)))
    """

    free: tuple[bool, ...] = field(default=(True,) * 6)

    @classmethod
    def of(cls, *labels: str) -> "ParamMask":
        unknown = [x for x in labels if x not in BASE_LABELS]
        if unknown:
            raise VisionCalError(f"no base parameter {unknown}: expected {BASE_LABELS}")
        return cls(tuple(x in labels for x in BASE_LABELS))

    def __or__(self, other: "ParamMask") -> "ParamMask":
        return ParamMask(tuple(a or b for a, b in zip(self.free, other.free)))

    @property
    def array(self) -> np.ndarray:
        return np.array(self.free, dtype=bool)

    @property
    def labels(self) -> tuple[str, ...]:
        """The free parameters' labels, in the vector's order."""
        return tuple(x for x, f in zip(BASE_LABELS, self.free) if f)

    def over(self, n_params: int) -> np.ndarray:
        """(n_params,) bool over a model's whole vector (base, then effects, held)."""
        out = np.zeros(n_params, bool)
        out[:6] = self.free
        return out


def _as_q_rad(q_deg) -> np.ndarray:
    q = np.atleast_2d(np.asarray(q_deg, dtype=float))
    if q.shape[-1] != 2:
        raise VisionCalError(f"joint angles must have shape (N, 2), got {q.shape}")
    return np.radians(q)


def forward_rad(p: np.ndarray, phi_rel: np.ndarray) -> np.ndarray:
    """FK from a parameter vector and *effective* joint angles (radians, before zeros).

    p: (6,) parameter vector; phi_rel: (N, 2) joint angles q (rad) to which z1, z2 are added.
    Returns (N, 2) pen positions in sheet mm.
    """
    a1 = phi_rel[:, 0] + p[2]
    a12 = a1 + phi_rel[:, 1] + p[3]
    x = p[4] + p[0] * np.cos(a1) + p[1] * np.cos(a12)
    y = p[5] + p[0] * np.sin(a1) + p[1] * np.sin(a12)
    return np.stack([x, y], axis=-1)


def jacobian_rad(p: np.ndarray, phi_rel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Analytic Jacobians of :func:`forward_rad`.

    Returns ``(J_params, J_joints)``: (N, 2, 6) w.r.t. the parameter vector and
    (N, 2, 2) w.r.t. the effective joint angles (rad).
    """
    a1 = phi_rel[:, 0] + p[2]
    a12 = a1 + phi_rel[:, 1] + p[3]
    c1, s1, c12, s12 = np.cos(a1), np.sin(a1), np.cos(a12), np.sin(a12)
    n = len(a1)
    jp = np.zeros((n, 2, 6))
    jp[:, 0, 0], jp[:, 1, 0] = c1, s1
    jp[:, 0, 1], jp[:, 1, 1] = c12, s12
    jp[:, 0, 2] = -p[0] * s1 - p[1] * s12
    jp[:, 1, 2] = p[0] * c1 + p[1] * c12
    jp[:, 0, 3] = -p[1] * s12
    jp[:, 1, 3] = p[1] * c12
    jp[:, 0, 4] = 1.0
    jp[:, 1, 5] = 1.0
    jq = np.empty((n, 2, 2))
    jq[:, :, 0] = jp[:, :, 2]
    jq[:, :, 1] = jp[:, :, 3]
    return jp, jq


def flange_angle_rad(p: np.ndarray, phi_rel: np.ndarray) -> np.ndarray:
    """``phi1 + phi2`` (N,) rad: the direction of link 2 in the sheet frame, which is the
    flange frame's x axis at commanded ``q4 = 0`` (p and phi_rel as in :func:`forward_rad`)."""
    return phi_rel[:, 0] + p[2] + phi_rel[:, 1] + p[3]


def tool_offset_rad(tool_mm, angle_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The tool term ``Rot(angle) tool`` (N, 2) mm and its derivative w.r.t. the angle
    (N, 2) mm/rad, for ``angle = phi1 + phi2 + q4`` (N,) rad and ``tool_mm`` (2,)."""
    tx, ty = float(tool_mm[0]), float(tool_mm[1])
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    off = np.stack([c * tx - s * ty, s * tx + c * ty], axis=-1)
    d = np.stack([-s * tx - c * ty, c * tx - s * ty], axis=-1)
    return off, d


def forward_tool(params: ScaraParams, q_deg, q4_deg=0.0, tool_mm=(0.0, 0.0)) -> np.ndarray:
    """Pen positions (N, 2) in sheet mm with a tool: commanded joints ``q_deg`` (N, 2),
    joint 4 ``q4_deg`` (N,) or scalar, ``tool_mm`` (2,) in the flange frame (contract
    "Joint 4 and the tool"). ``tool_mm = [0, 0]`` is :func:`forward`."""
    q = _as_q_rad(q_deg)
    q4 = np.broadcast_to(np.radians(np.asarray(q4_deg, dtype=float)), (len(q),))
    p = params.vector
    off, _ = tool_offset_rad(tool_mm, flange_angle_rad(p, q) + q4)
    return forward_rad(p, q) + off


def forward(params: ScaraParams, q_deg) -> np.ndarray:
    """Pen positions (N, 2) in sheet mm for commanded joints ``q_deg`` (N, 2)."""
    return forward_rad(params.vector, _as_q_rad(q_deg))


def jacobian(params: ScaraParams, q_deg) -> np.ndarray:
    """d pen / d vector, (N, 2, 6), in mm per internal unit (mm or rad)."""
    return jacobian_rad(params.vector, _as_q_rad(q_deg))[0]


def inverse(params: ScaraParams, xy_mm, *, elbow: int = 1, min_sin_q2: float = 0.0,
            on_fail: str = "raise") -> np.ndarray:
    """Commanded joints (N, 2) in degrees that put the pen on ``xy_mm`` (N, 2).

    ``elbow=+1`` picks sin(phi2) > 0 (elbow on the counter-clockwise side),
    ``elbow=-1`` the other solution. Raises :class:`VisionCalError` naming the first
    unreachable point (or one closer to the singularity than ``min_sin_q2``); with
    ``on_fail="nan"`` such points get NaN joints instead (see :func:`ik_failures`).
    """
    if elbow not in (1, -1):
        raise VisionCalError(f"elbow must be +1 or -1, got {elbow!r}")
    xy = np.atleast_2d(np.asarray(xy_mm, dtype=float))
    d = xy - np.array(params.base_mm)
    r2 = np.sum(d**2, axis=1)
    L1, L2 = params.L1_mm, params.L2_mm
    c2 = (r2 - L1**2 - L2**2) / (2 * L1 * L2)
    bad = np.flatnonzero(~(np.abs(c2) <= 1.0))
    if on_fail == "nan":
        s2 = elbow * np.sqrt(np.clip(1.0 - c2**2, 0.0, None))
        fail = ~(np.abs(c2) <= 1.0) | (np.abs(s2) < min_sin_q2)
        q = _ik_angles(params, d, c2, s2)
        q[fail] = np.nan
        return q
    if bad.size:
        i = int(bad[0])
        raise VisionCalError(
            f"point {i} at ({xy[i, 0]:.3f}, {xy[i, 1]:.3f}) mm is out of reach: it is "
            f"{np.sqrt(r2[i]):.3f} mm from the base, the arm reaches "
            f"{abs(L1 - L2):.3f}..{L1 + L2:.3f} mm")
    s2 = elbow * np.sqrt(np.clip(1.0 - c2**2, 0.0, None))
    near = np.flatnonzero(np.abs(s2) < min_sin_q2)
    if near.size:
        i = int(near[0])
        raise VisionCalError(
            f"point {i} at ({xy[i, 0]:.3f}, {xy[i, 1]:.3f}) mm is too close to the "
            f"singularity (|sin phi2| = {abs(s2[i]):.4f} < {min_sin_q2})")
    return _ik_angles(params, d, c2, s2)


def _ik_angles(params: ScaraParams, d, c2, s2) -> np.ndarray:
    L1, L2 = params.L1_mm, params.L2_mm
    phi2 = np.arctan2(s2, c2)
    phi1 = np.arctan2(d[:, 1], d[:, 0]) - np.arctan2(L2 * s2, L1 + L2 * c2)
    q = np.stack([phi1 - np.radians(params.z1_deg), phi2 - np.radians(params.z2_deg)], axis=1)
    q = (q + np.pi) % (2 * np.pi) - np.pi
    return np.degrees(q)


def ik_failures(params: ScaraParams, xy_mm, *, min_sin_q2: float = 0.0) -> list[str]:
    """Why each point (N, 2) cannot be reached ("" where it can)."""
    xy = np.atleast_2d(np.asarray(xy_mm, dtype=float))
    r = np.hypot(*(xy - np.array(params.base_mm)).T)
    L1, L2 = params.L1_mm, params.L2_mm
    c2 = (r**2 - L1**2 - L2**2) / (2 * L1 * L2)
    out = []
    for p, ri, ci in zip(xy, r, c2):
        if not abs(ci) <= 1.0:
            out.append(f"({p[0]:.3f}, {p[1]:.3f}) mm is out of reach: it is {ri:.3f} mm from "
                       f"the base, the arm reaches {abs(L1 - L2):.3f}..{L1 + L2:.3f} mm")
        elif np.sqrt(max(1.0 - ci**2, 0.0)) < min_sin_q2:
            out.append(f"({p[0]:.3f}, {p[1]:.3f}) mm is too close to the singularity "
                       f"(|sin phi2| = {np.sqrt(max(1.0 - ci**2, 0.0)):.4f} < {min_sin_q2})")
        else:
            out.append("")
    return out
