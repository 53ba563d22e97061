"""The synthetic world's own robot: every injected effect written out from the contract.

This module deliberately shares **no code** with the estimator (``vision_cal.model.robot``,
``vision_cal.model.kinematics``): it reads the format's JSON blocks (``params`` and ``effects``
of truth.json, docs/format.md) and computes where the pen really is from
the contract's formulas, so a sign or convention error in the estimator cannot cancel
against the same error in the world. Frames and units as in docs/conventions.md.

Joints. With ``q`` the commanded angle and ``s`` the side the joint arrived from (+1: it
last turned counter-clockwise), the angle a joint really turns to is::

    q_link = q  - s * band / 2                       joint_backlash (lags against approach)
                + scale * q                          joint_scale    (turns (1+scale) q)
                + A * sin(h * q + phase)             joint_cyclic

                + sum_k coef_k * f_k(q1, q2, s1, s2)  joint_terms (coupling, polynomial)

every term evaluated at the commanded ``q`` (degrees here; the cyclic argument in radians).
A ``joint_terms`` feature is a product of factors ``q1``, ``q2``, ``q1^p``, ``sin(h*q1)``,
``cos(h*q2)`` (argument in degrees), ``approach1``, ``approach2`` (docs/format.md).

Drift (``drift``, world fields ``param``, ``change``, ``shape``, ``tau``): one base
parameter (``L1_mm``, ``L2_mm``, ``z1_deg``, ``z2_deg``, ``base_x_mm``, ``base_y_mm``)
changes while the marks are drawn; with ``t`` = 0 at the first mark and 1 at the last::

    linear:  p(t) = p + change * t
    warmup:  p(t) = p + change * (1 - exp(-t / tau)) / (1 - exp(-1 / tau))

so ``change`` is the change from the first to the last mark in both shapes.

Arm plane. The arm moves in a physical plane (the *arm frame*, mm): the link angles are
measured from its x axis, ``phi1 = q_link1 + z1``, ``phi2 = q_link2 + z2``, and::

    elbow = base + L1 (cos phi1, sin phi1)
    pen   = elbow + L2 (cos(phi1 + phi2), sin(phi1 + phi2))

Joint 4 and the tool (contract "Joint 4 and the tool"). Commands may be ``(N, 3)``:
``[q1, q2, q4]``. Joint 4 really turns to ``q4 - s4 * band4 / 2 + scale4 * q4`` (its own
backlash and gear ratio, ``s4`` its approach side) and the pen sits at ``tool_mm`` in the
flange frame, turned by the flange's direction ``phi1 + phi2 + q4_real``::

    pen = elbow + L2 (cos(phi1 + phi2), sin(phi1 + phi2))
                + (cos a tx - sin a ty, sin a tx + cos a ty),   a = phi1 + phi2 + q4_real

Sheet. ``sheet_affine`` says the paper has deformed since it was printed (paper shrink):
a point printed at ``p`` (sheet frame S, the coordinates of the sheet description) now lies
at ``A p`` in the arm frame, with ``A = inv(matrix)`` about the sheet origin, so a pen
position ``x`` in the arm frame reads ``matrix @ x`` on the printed sheet. The renderer
places the printed texture and its markers at ``A p`` (physically shrunk, see
:meth:`TrueRobot.T_render`); the marks are drawn into the texture at ``matrix @ x``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vision_cal.errors import VisionCalError


@dataclass(frozen=True)
class Cyclic:
    joint: int          # 1 or 2
    harmonic: int
    deg: float
    phase_deg: float


@dataclass(frozen=True)
class Term:
    joint: int          # 1 or 2: the joint that turns coef * feature degrees more
    feature: str
    coef: float


DRIFT_PARAMS = ("L1_mm", "L2_mm", "z1_deg", "z2_deg", "base_x_mm", "base_y_mm")


@dataclass(frozen=True)
class Drift:
    param: str          # one of DRIFT_PARAMS
    change: float       # mm or deg, first to last mark
    shape: str = "linear"   # linear | warmup
    tau: float = 0.2    # warmup: time constant as a fraction of the session

    def at(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        if self.shape == "linear":
            return self.change * t
        return self.change * (1.0 - np.exp(-t / self.tau)) / (1.0 - math.exp(-1.0 / self.tau))


def _feature(feature: str, q: np.ndarray, s: np.ndarray) -> np.ndarray:
    """The world's own reading of a joint_terms feature (q in degrees, s signs)."""
    val = np.ones(len(q))
    parts, depth, cur = [], 0, ""
    for ch in feature.replace(" ", ""):
        depth += (ch == "(") - (ch == ")")
        if ch == "*" and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    parts.append(cur)
    for f in parts:
        if f[:4] in ("sin(", "cos(") and f.endswith(")"):
            inner = f[4:-1]
            h, _, qj = inner.rpartition("*")
            j = {"q1": 0, "q2": 1}[qj]
            arg = (float(h) if h else 1.0) * np.radians(q[:, j])
            val = val * (np.sin(arg) if f[:3] == "sin" else np.cos(arg))
        elif f.startswith("approach"):
            val = val * s[:, {"approach1": 0, "approach2": 1}[f]]
        else:
            base, _, power = f.partition("^")
            val = val * q[:, {"q1": 0, "q2": 1}[base]] ** (int(power) if power else 1)
    return val


@dataclass(frozen=True)
class TrueRobot:
    """The true robot of a synthetic world (mm, degrees)."""

    L1_mm: float
    L2_mm: float
    zero_deg: tuple[float, float]
    base_mm: tuple[float, float]
    backlash_deg: tuple[float, float] = (0.0, 0.0)   # full dead band per joint
    scale: tuple[float, float] = (0.0, 0.0)          # gear-ratio error per joint
    cyclic: tuple[Cyclic, ...] = ()
    sheet_matrix: tuple[tuple[float, float], tuple[float, float]] = ((1.0, 0.0), (0.0, 1.0))
    terms: tuple[Term, ...] = ()
    drift: tuple[Drift, ...] = ()
    tool_mm: tuple[float, float] = (0.0, 0.0)        # pen in the flange frame at q4 = 0
    backlash4_deg: float = 0.0                       # joint 4's full dead band
    scale4: float = 0.0                              # joint 4's gear-ratio error

    # ------------------------------------------------------------------ JSON reading

    @classmethod
    def from_json(cls, params: dict, effects=()) -> "TrueRobot":
        """From truth.json's ``params`` and ``effects`` blocks (format names)."""
        try:
            L1, L2 = float(params["L1_mm"]), float(params["L2_mm"])
            z = (float(params["joint_zero_deg"][0]), float(params["joint_zero_deg"][1]))
            b = (float(params["base_mm"][0]), float(params["base_mm"][1]))
        except (KeyError, TypeError, ValueError, IndexError) as e:
            raise VisionCalError(f"malformed params {params!r}: {e}", field="params") from e
        try:
            tool = tuple(float(v) for v in params.get("tool_mm", (0.0, 0.0)))
            if len(tool) != 2:
                raise ValueError("tool_mm must be [x, y]")
        except (TypeError, ValueError) as e:
            raise VisionCalError(f"malformed params.tool_mm: {e}", field="params") from e
        band, scale, cyc, terms, drift = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [], [], []
        matrix = ((1.0, 0.0), (0.0, 1.0))
        for d in effects:
            try:
                name = d["name"]
                if name in ("joint_backlash", "joint_scale", "joint_cyclic", "joint_terms"):
                    j = int(d["joint"])
                    ok = (1, 2, 4) if name in ("joint_backlash", "joint_scale") else (1, 2)
                    if j not in ok:
                        raise ValueError(f"joint must be one of {ok}, got {j}")
                    j = 3 if j == 4 else j
                if name == "joint_backlash":
                    band[j - 1] += float(d["deg"])
                elif name == "joint_scale":
                    scale[j - 1] += float(d["scale"])
                elif name == "joint_cyclic":
                    cyc.append(Cyclic(j, int(d["harmonic"]), float(d["deg"]),
                                      float(d.get("phase_deg", 0.0))))
                elif name == "joint_terms":
                    for t in d["terms"]:
                        f = str(t["feature"])
                        _feature(f, np.zeros((1, 2)), np.ones((1, 2)))   # readable?
                        terms.append(Term(j, f, float(t["coef"])))
                elif name == "drift":
                    if d["param"] not in DRIFT_PARAMS:
                        raise ValueError(f"drift param must be one of {DRIFT_PARAMS}")
                    shape = d.get("shape", "linear")
                    if shape not in ("linear", "warmup"):
                        raise ValueError("drift shape must be linear or warmup")
                    tau = float(d.get("tau", 0.2))
                    if not tau > 0:
                        raise ValueError("drift tau must be > 0")
                    drift.append(Drift(d["param"], float(d["change"]), shape, tau))
                elif name == "sheet_affine":
                    m = [[float(v) for v in row] for row in d["matrix"]]
                    if len(m) != 2 or any(len(r) != 2 for r in m):
                        raise ValueError("matrix must be 2x2")
                    a, b2 = matrix
                    # a later affine acts after the earlier ones: total = m @ total
                    matrix = ((m[0][0] * a[0] + m[0][1] * b2[0], m[0][0] * a[1] + m[0][1] * b2[1]),
                              (m[1][0] * a[0] + m[1][1] * b2[0], m[1][0] * a[1] + m[1][1] * b2[1]))
                elif name in ("lens_distortion", "sheet_height"):
                    continue   # the camera's / the paper's, not the robot's
                else:
                    raise ValueError(f"unknown effect {name!r}")
            except (KeyError, TypeError, ValueError, IndexError) as e:
                raise VisionCalError(f"malformed effect {d!r}: {e}", field="effects") from e
        return cls(L1, L2, z, b, tuple(band[:2]), tuple(scale[:2]), tuple(cyc), matrix,
                   tuple(terms), tuple(drift), tool, band[2], scale[2])

    def without_backlash(self) -> "TrueRobot":
        """The same robot with the dead band of joints 1 and 2 taken out (a simulated gear
        play owns it; joint 4 is not simulated and keeps its own)."""
        return TrueRobot(self.L1_mm, self.L2_mm, self.zero_deg, self.base_mm, (0.0, 0.0),
                         self.scale, self.cyclic, self.sheet_matrix, self.terms, self.drift,
                         self.tool_mm, self.backlash4_deg, self.scale4)

    # ------------------------------------------------------------------ joints

    def link_deg(self, q_deg, approach=None) -> np.ndarray:
        """Angles (N, 2) deg the links really turn to for commands ``q_deg`` (N, 2) reached
        from sides ``approach`` (N, 2) of +-1 (None: +1)."""
        q = np.array(q_deg, dtype=float, ndmin=2)[:, :2]
        a = None if approach is None else np.array(approach, dtype=float, ndmin=2)
        s = np.ones_like(q) if a is None else np.where(
            np.broadcast_to(a[:, :2] if a.shape[-1] == 3 else a, q.shape) < 0, -1.0, 1.0)
        out = q.copy()
        for j in range(2):
            out[:, j] += -s[:, j] * self.backlash_deg[j] / 2.0 + self.scale[j] * q[:, j]
        for c in self.cyclic:
            qj = q[:, c.joint - 1]
            out[:, c.joint - 1] += c.deg * np.sin(c.harmonic * np.radians(qj)
                                                  + math.radians(c.phase_deg))
        for t in self.terms:
            out[:, t.joint - 1] += t.coef * _feature(t.feature, q, s)
        return out

    # ------------------------------------------------------------------ arm frame

    def arm_points(self, link_deg, t=None) -> np.ndarray:
        """(N, 3, 2) base, elbow, pen in the arm frame (mm) for link angles (N, 2) deg,
        drawn at times ``t`` (N,) (0: first mark, 1: last; None: 0, no drift)."""
        a = np.array(link_deg, dtype=float, ndmin=2)
        p = {"L1_mm": self.L1_mm, "L2_mm": self.L2_mm, "z1_deg": self.zero_deg[0],
             "z2_deg": self.zero_deg[1], "base_x_mm": self.base_mm[0],
             "base_y_mm": self.base_mm[1]}
        p = {k: np.full(len(a), float(v)) for k, v in p.items()}
        tt = np.zeros(len(a)) if t is None else np.broadcast_to(np.asarray(t, float), (len(a),))
        for d in self.drift:
            p[d.param] = p[d.param] + d.at(tt)
        phi1 = np.radians(a[:, 0] + p["z1_deg"])
        phi12 = phi1 + np.radians(a[:, 1] + p["z2_deg"])
        bx, by = p["base_x_mm"], p["base_y_mm"]
        ex = bx + p["L1_mm"] * np.cos(phi1)
        ey = by + p["L1_mm"] * np.sin(phi1)
        px = ex + p["L2_mm"] * np.cos(phi12)
        py = ey + p["L2_mm"] * np.sin(phi12)
        base = np.column_stack([bx, by])
        return np.stack([base, np.column_stack([ex, ey]), np.column_stack([px, py])], axis=1)

    # ------------------------------------------------------------------ sheet

    @property
    def M(self) -> np.ndarray:
        """Arm frame -> printed sheet coordinates (2, 2)."""
        return np.array(self.sheet_matrix, dtype=float)

    def to_sheet(self, xy_arm_mm) -> np.ndarray:
        """Arm-frame points (N, 2) -> printed sheet coordinates (N, 2)."""
        return np.asarray(xy_arm_mm, dtype=float).reshape(-1, 2) @ self.M.T

    def T_render(self, T_cam_arm) -> np.ndarray:
        """4x4 map printed sheet point (x, y, z, 1) -> camera, for a camera at rigid pose
        ``T_cam_arm`` (arm frame -> camera): the printed point ``p`` lies at ``inv(M) p``.
        An affine (not rigid) 4x4 when the sheet is deformed; OpenGL and projection take it
        as it is."""
        A = np.eye(4)
        A[:2, :2] = np.linalg.inv(self.M)
        return np.asarray(T_cam_arm, dtype=float) @ A

    # ------------------------------------------------------------------ the pen

    def joint4_deg(self, q_deg, approach=None) -> np.ndarray:
        """The angle (N,) deg joint 4 really turns to: commands ``q_deg`` (N, 3) (0 for
        (N, 2)), approach side from ``approach``'s third column (+1 when absent)."""
        q = np.array(q_deg, dtype=float, ndmin=2)
        q4 = q[:, 2] if q.shape[-1] == 3 else np.zeros(len(q))
        a = None if approach is None else np.array(approach, dtype=float, ndmin=2)
        s4 = np.where(a[:, 2] < 0, -1.0, 1.0) if a is not None and a.shape[-1] == 3 else 1.0
        return q4 - s4 * self.backlash4_deg / 2.0 + self.scale4 * q4

    def pen_mm(self, q_deg, approach=None, *, link=False, t=None) -> np.ndarray:
        """Pen positions (N, 2) on the printed sheet: commands ``q_deg`` (N, 2) or
        (N, 3) with joint 4, reached from ``approach`` (or, with ``link=True``, links
        already at ``q_deg``: no joint effects on joints 1 and 2), drawn at times ``t``
        (N,) in [0, 1] (None: no drift)."""
        q = np.array(q_deg, dtype=float, ndmin=2)
        a = q[:, :2] if link else self.link_deg(q, approach)
        arm = self.arm_points(a, t)
        pen = arm[:, 2]
        tx, ty = self.tool_mm
        if tx or ty:   # the flange's direction is link 2's (drift included), plus joint 4
            d = arm[:, 2] - arm[:, 1]
            ang = np.arctan2(d[:, 1], d[:, 0]) + np.radians(self.joint4_deg(q, approach))
            pen = pen + np.column_stack([np.cos(ang) * tx - np.sin(ang) * ty,
                                         np.sin(ang) * tx + np.cos(ang) * ty])
        return self.to_sheet(pen)
