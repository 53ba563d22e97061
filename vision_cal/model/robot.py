"""The full robot model: the base model plus effects the base model lacks.

Every effect of docs/format.md that acts on the robot lives here with
its own Jacobian, so the same code fits (``estimate``) and compensates (``plan``); the
synthetic world (``world``) writes its truth with its own code.

Joint effects change the angle the joint really turns to. With ``q`` the commanded
angle (rad) and ``s`` the approach sign (+1: the joint last moved in the positive
direction), each adds a term evaluated at the *commanded* angle::

    joint_backlash   -s * band / 2            (lags against its approach direction)
    joint_scale      scale * q                (turns (1 + scale) times the command)
    joint_cyclic     A sin(h q + phase)       (once- or twice-per-turn error)

``sheet_affine`` maps the arm's planar position into printed sheet coordinates about
the sheet origin: ``pen_sheet = M @ pen_arm``. A uniform scale of M is the same as
scaling L1, L2 and the base, so only its uneven part is identifiable; the fitted
candidates stretch one sheet axis (see docs/conventions.md).

Joint 4 and the tool (contract "Joint 4 and the tool"). Commanded joints may be
``(N, 3)``: ``[q1, q2, q4]`` (``(N, 2)`` means ``q4 = 0``), approach signs ``(N, 2)`` or
``(N, 3)`` (joint 4's sign +1 when absent). A :class:`Tool` effect puts the pen at
``tool_mm`` in the flange frame (``pen += Rot(phi1 + phi2 + q4_real) tool``); joint
effects with ``joint=4`` change ``q4_real`` as those of joints 1 and 2 change theirs.
Without a :class:`Tool` the model is exactly the tool-less one.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from vision_cal.model import joint_terms as jt
from vision_cal.errors import VisionCalError
from vision_cal.model.kinematics import (ScaraParams, flange_angle_rad, forward_rad, jacobian_rad,
                                   tool_offset_rad)


def _check_joint(joint, where: str, allowed=(1, 2)) -> int:
    if joint not in allowed or isinstance(joint, bool):
        raise VisionCalError(f"joint must be {' or '.join(map(str, allowed))}, got {joint!r}",
                             field=where)
    return int(joint)


@dataclass(frozen=True)
class Effect:
    """One effect added to the base model. ``theta`` is its flat vector (internal units)."""

    name: ClassVar[str] = ""
    param_names: ClassVar[tuple[str, ...]] = ()

    @property
    def theta(self) -> np.ndarray:
        raise NotImplementedError

    def with_theta(self, theta: np.ndarray) -> "Effect":
        raise NotImplementedError

    @property
    def label(self) -> str:
        return self.name

    def to_json(self, std: np.ndarray | None = None) -> dict:
        raise NotImplementedError


@dataclass(frozen=True)
class JointEffect(Effect):
    joint: int = 1

    def delta(self, q: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint angle added (N,) rad and its derivative (N, k) w.r.t. theta."""
        raise NotImplementedError

    @property
    def label(self) -> str:
        return f"{self.name}(joint {self.joint})"


@dataclass(frozen=True)
class JointBacklash(JointEffect):
    """Dead band of ``deg`` (full band); the joint lags by half of it."""

    name: ClassVar[str] = "joint_backlash"
    param_names: ClassVar[tuple[str, ...]] = ("deg",)
    deg: float = 0.0

    @property
    def theta(self):
        return np.array([np.radians(self.deg)])

    def with_theta(self, theta):
        return replace(self, deg=float(np.degrees(theta[0])))

    def delta(self, q, s):
        return -0.5 * s * np.radians(self.deg), (-0.5 * s)[:, None]

    def to_json(self, std=None):
        d = {"name": self.name, "joint": self.joint, "deg": self.deg}
        if std is not None:
            d["std"] = float(np.degrees(std[0]))
        return d


@dataclass(frozen=True)
class JointScale(JointEffect):
    """Gear-ratio error: the joint turns (1 + scale) times the command."""

    name: ClassVar[str] = "joint_scale"
    param_names: ClassVar[tuple[str, ...]] = ("scale",)
    scale: float = 0.0

    @property
    def theta(self):
        return np.array([self.scale])

    def with_theta(self, theta):
        return replace(self, scale=float(theta[0]))

    def delta(self, q, s):
        return self.scale * q, q[:, None]

    def to_json(self, std=None):
        d = {"name": self.name, "joint": self.joint, "scale": self.scale}
        if std is not None:
            d["std"] = float(std[0])
        return d


@dataclass(frozen=True)
class JointCyclic(JointEffect):
    """``deg * sin(harmonic * q + phase)``; fitted linearly as ``a sin(hq) + b cos(hq)``."""

    name: ClassVar[str] = "joint_cyclic"
    param_names: ClassVar[tuple[str, ...]] = ("sin_deg", "cos_deg")
    harmonic: int = 1
    deg: float = 0.0
    phase_deg: float = 0.0

    @property
    def label(self) -> str:
        return f"{self.name}(joint {self.joint}, harmonic {self.harmonic})"

    @property
    def theta(self):
        a = np.radians(self.deg)
        p = np.radians(self.phase_deg)
        return np.array([a * np.cos(p), a * np.sin(p)])

    def with_theta(self, theta):
        amp = float(np.degrees(np.hypot(theta[0], theta[1])))
        phase = float(np.degrees(np.arctan2(theta[1], theta[0])))
        return replace(self, deg=amp, phase_deg=phase)

    def delta(self, q, s):
        sh, ch = np.sin(self.harmonic * q), np.cos(self.harmonic * q)
        th = self.theta
        return th[0] * sh + th[1] * ch, np.stack([sh, ch], axis=1)

    def to_json(self, std=None):
        d = {"name": self.name, "joint": self.joint, "harmonic": self.harmonic,
             "deg": self.deg, "phase_deg": self.phase_deg}
        if std is not None:
            # one standard deviation of the amplitude (radial component), degrees
            th = self.theta
            amp = np.hypot(*th)
            u = th / amp if amp > 0 else np.array([1.0, 0.0])
            d["std"] = float(np.degrees(np.hypot(u[0] * std[0], u[1] * std[1])))
        return d


@dataclass(frozen=True)
class JointTerms(JointEffect):
    """A joint error found from the residual: the joint turns ``sum(coef_k * f_k)`` degrees
    more than commanded, ``f_k`` features of both commanded angles and approach signs
    (:mod:`vision_cal.model.joint_terms`). Internally ``theta_k = radians(coef_k) * unit(f_k)``."""

    name: ClassVar[str] = "joint_terms"
    features: tuple[str, ...] = ()
    coef_deg: tuple[float, ...] = ()

    @property
    def param_names(self):
        return tuple(self.features)

    @property
    def label(self) -> str:
        return f"{self.name}(joint {self.joint}: {', '.join(self.features)})"

    @property
    def theta(self):
        c = self.coef_deg or (0.0,) * len(self.features)
        return np.array([np.radians(v) * jt.unit(f) for v, f in zip(c, self.features)])

    def with_theta(self, theta):
        return replace(self, coef_deg=tuple(float(np.degrees(t) / jt.unit(f))
                                            for t, f in zip(theta, self.features)))

    def delta_all(self, q_rad: np.ndarray, s: np.ndarray):
        """Angle added (N,) rad and its derivative (N, k), from both joints (N, 2)."""
        qd = np.degrees(q_rad)
        cols = np.stack([jt.evaluate(f, qd, s) / jt.unit(f) for f in self.features], axis=1) \
            if self.features else np.zeros((len(qd), 0))
        return cols @ self.theta, cols

    def to_json(self, std=None):
        terms = []
        for k, (f, c) in enumerate(zip(self.features, self.coef_deg or (0.0,) * len(self.features))):
            t = {"feature": f, "coef": c}
            if std is not None:
                t["std"] = float(np.degrees(std[k]) / jt.unit(f))
            terms.append(t)
        return {"name": self.name, "joint": self.joint, "terms": terms,
                "description": "; ".join(jt.describe(self.joint, t["feature"], t["coef"])
                                         for t in terms)}


@dataclass(frozen=True)
class SheetAffine(Effect):
    """Printed sheet coordinates = ``matrix @`` arm position (about the sheet origin).

    ``dof`` says which entries are free when fitted: ``"x"`` or ``"y"`` (that axis
    scaled; the uniform part is the same as the link lengths, so one axis is fixed),
    ``"shear"`` (symmetric shear), ``"fixed"`` (none: truth or a given matrix).
    """

    name: ClassVar[str] = "sheet_affine"
    matrix: tuple[tuple[float, float], tuple[float, float]] = ((1.0, 0.0), (0.0, 1.0))
    dof: str = "fixed"

    @property
    def param_names(self):
        return {"x": ("sx",), "y": ("sy",), "shear": ("k",), "fixed": ()}[self.dof]

    @property
    def label(self) -> str:
        return f"{self.name}({self.dof})" if self.dof != "fixed" else self.name

    @property
    def M(self) -> np.ndarray:
        return np.array(self.matrix, dtype=float)

    @property
    def theta(self):
        m = self.M
        return {"x": np.array([m[0, 0] - 1.0]), "y": np.array([m[1, 1] - 1.0]),
                "shear": np.array([m[0, 1]]), "fixed": np.zeros(0)}[self.dof]

    def with_theta(self, theta):
        m = self.M.copy()
        if self.dof == "x":
            m[0, 0] = 1.0 + theta[0]
        elif self.dof == "y":
            m[1, 1] = 1.0 + theta[0]
        elif self.dof == "shear":
            m[0, 1] = m[1, 0] = theta[0]
        return replace(self, matrix=tuple(map(tuple, m.tolist())))

    def d_matrix(self) -> list[np.ndarray]:
        """dM/dtheta_k for each free parameter."""
        e = np.zeros((2, 2))
        if self.dof == "x":
            e[0, 0] = 1
        elif self.dof == "y":
            e[1, 1] = 1
        elif self.dof == "shear":
            e[0, 1] = e[1, 0] = 1
        else:
            return []
        return [e]

    def to_json(self, std=None):
        d = {"name": self.name, "matrix": [list(r) for r in self.M.tolist()]}
        if self.dof != "fixed":
            d["axis"] = self.dof
        if std is not None and len(std):
            d["std"] = float(std[0])
        return d


@dataclass(frozen=True)
class Tool(Effect):
    """The pen off the joint-4 axis: ``tool_mm`` (2,) in the flange frame at commanded
    ``q4 = 0`` (contract "Joint 4 and the tool"; it absorbs joint 4's zero offset).
    calibration.json reports it as ``params.tool_mm`` (``std.tool_mm``), not in ``effects``."""

    name: ClassVar[str] = "tool"
    param_names: ClassVar[tuple[str, ...]] = ("x_mm", "y_mm")
    tool_mm: tuple[float, float] = (0.0, 0.0)

    @property
    def theta(self):
        return np.array(self.tool_mm, dtype=float)

    def with_theta(self, theta):
        return replace(self, tool_mm=(float(theta[0]), float(theta[1])))

    def to_json(self, std=None):
        d = {"name": self.name, "tool_mm": [float(v) for v in self.tool_mm]}
        if std is not None:
            d["std"] = [float(v) for v in std]
        return d


def effect_from_json(d: dict, *, where: str = "effects") -> Effect:
    """Build an effect from its format dictionary (names as in docs/format.md)."""
    try:
        name = d["name"]
        if name == "joint_backlash":
            return JointBacklash(joint=_check_joint(d["joint"], where, (1, 2, 4)),
                                 deg=float(d["deg"]))
        if name == "joint_scale":
            return JointScale(joint=_check_joint(d["joint"], where, (1, 2, 4)),
                              scale=float(d["scale"]))
        if name == "joint_cyclic":
            h = int(d["harmonic"])
            if h not in (1, 2):
                raise VisionCalError(f"harmonic must be 1 or 2, got {h}", field=where)
            return JointCyclic(joint=_check_joint(d["joint"], where), harmonic=h,
                               deg=float(d["deg"]), phase_deg=float(d.get("phase_deg", 0.0)))
        if name == "joint_terms":
            terms = d["terms"]
            if not isinstance(terms, list) or not terms:
                raise VisionCalError("terms must be a non-empty list", field=where)
            fs = tuple(jt.check_feature(t["feature"], f"{where}.terms[{i}].feature")
                       for i, t in enumerate(terms))
            return JointTerms(joint=_check_joint(d["joint"], where), features=fs,
                              coef_deg=tuple(float(t["coef"]) for t in terms))
        if name == "sheet_affine":
            m = np.asarray(d["matrix"], dtype=float)
            if m.shape != (2, 2) or not np.all(np.isfinite(m)):
                raise VisionCalError("matrix must be 2x2 finite numbers", field=where)
            return SheetAffine(matrix=tuple(map(tuple, m.tolist())), dof=d.get("axis", "fixed"))
    except (KeyError, TypeError, ValueError) as e:
        raise VisionCalError(f"malformed effect {d!r}: {e}", field=where) from e
    raise VisionCalError(f"effect {d.get('name')!r} does not act on the robot model", field=where)


@dataclass(frozen=True)
class RobotModel:
    """Base parameters plus effects. The flat vector is base (6) then each effect's theta."""

    params: ScaraParams
    effects: tuple[Effect, ...] = ()

    @property
    def sizes(self) -> list[int]:
        return [6] + [len(e.theta) for e in self.effects]

    @property
    def vector(self) -> np.ndarray:
        return np.concatenate([self.params.vector] + [e.theta for e in self.effects])

    def with_vector(self, v: np.ndarray) -> "RobotModel":
        v = np.asarray(v, dtype=float)
        parts = np.split(v, np.cumsum(self.sizes)[:-1])
        effects = tuple(e.with_theta(p) for e, p in zip(self.effects, parts[1:]))
        return RobotModel(ScaraParams.from_vector(parts[0]), effects)

    def with_effect(self, effect: Effect) -> "RobotModel":
        return RobotModel(self.params, self.effects + (effect,))

    @staticmethod
    def _approach(q: np.ndarray, approach) -> np.ndarray:
        if approach is None:
            return np.ones_like(q)
        a = np.asarray(approach, dtype=float)
        if a.ndim == 2 and a.shape[-1] == 3 and q.shape[-1] == 2:
            a = a[:, :2]
        s = np.broadcast_to(a, q.shape)
        return np.where(s < 0, -1.0, 1.0)

    @staticmethod
    def _joint4(q_deg, approach) -> tuple[np.ndarray, np.ndarray]:
        """Commanded joint 4 (N,) rad (0 for (N, 2) joints) and its approach sign (N,)."""
        q = np.atleast_2d(np.asarray(q_deg, dtype=float))
        q4 = np.radians(q[:, 2]) if q.shape[-1] == 3 else np.zeros(len(q))
        a = None if approach is None else np.atleast_2d(np.asarray(approach, dtype=float))
        s4 = (np.where(a[:, 2] < 0, -1.0, 1.0) if a is not None and a.shape[-1] == 3
              else np.ones(len(q)))
        return q4, s4

    @property
    def tool(self) -> "Tool | None":
        """The :class:`Tool` effect, if the model has one."""
        return next((e for e in self.effects if isinstance(e, Tool)), None)

    def joint_angles_rad(self, q_deg, approach=None) -> np.ndarray:
        """Angles (N, 2) joints 1 and 2 really turn to (rad, before the zero offsets)."""
        q = np.radians(np.atleast_2d(np.asarray(q_deg, dtype=float))[:, :2])
        s = self._approach(q, approach)
        out = q.copy()
        for e in self.effects:
            if isinstance(e, JointTerms):
                out[:, e.joint - 1] += e.delta_all(q, s)[0]
            elif isinstance(e, JointEffect) and e.joint in (1, 2):
                j = e.joint - 1
                out[:, j] += e.delta(q[:, j], s[:, j])[0]
        return out

    def joint4_rad(self, q_deg, approach=None) -> np.ndarray:
        """The angle (N,) rad joint 4 really turns to (its commanded angle plus joint-4
        effects; 0 plus effects for (N, 2) joints)."""
        q4, s4 = self._joint4(q_deg, approach)
        out = q4.copy()
        for e in self.effects:
            if isinstance(e, JointEffect) and e.joint == 4:
                out += e.delta(q4, s4)[0]
        return out

    def tool_term(self, q_deg, approach=None) -> np.ndarray:
        """``Rot(phi1 + phi2 + q4) tool`` (N, 2) in the arm frame (zeros without a tool)."""
        tool = self.tool
        phi = self.joint_angles_rad(q_deg, approach)
        if tool is None:
            return np.zeros((len(phi), 2))
        ang = flange_angle_rad(self.params.vector, phi) + self.joint4_rad(q_deg, approach)
        return tool_offset_rad(tool.tool_mm, ang)[0]

    def joint_columns(self, q_deg, approach=None) -> np.ndarray:
        """(N, 2, 2): the sheet displacement (mm) per radian added to joint 1 (``[..., 0]``)
        and joint 2 (``[..., 1]``) at the angles the joints really turn to; with a tool, the
        tool turns with them. The column a joint error's effect is scaled from (diagnosis)."""
        phi = self.joint_angles_rad(q_deg, approach)
        p = self.params.vector
        _, jq = jacobian_rad(p, phi)
        tool = self.tool
        if tool is not None:
            ang = flange_angle_rad(p, phi) + self.joint4_rad(q_deg, approach)
            d_ang = tool_offset_rad(tool.tool_mm, ang)[1]
            jq = jq + d_ang[:, :, None]
        return np.einsum("ij,njk->nik", self.sheet_matrix(), jq)

    def sheet_matrix(self) -> np.ndarray:
        m = np.eye(2)
        for e in self.effects:
            if isinstance(e, SheetAffine):
                m = e.M @ m
        return m

    def predict(self, q_deg, approach=None) -> np.ndarray:
        """Pen positions (N, 2) in sheet mm for commanded ``q_deg`` (N, 2) and approach signs."""
        phi = self.joint_angles_rad(q_deg, approach)
        xy = forward_rad(self.params.vector, phi)
        if self.tool is not None:
            xy = xy + self.tool_term(q_deg, approach)
        return xy @ self.sheet_matrix().T

    def jacobian(self, q_deg, approach=None) -> np.ndarray:
        """d predict / d vector: (N, 2, P), analytic."""
        q = np.radians(np.atleast_2d(np.asarray(q_deg, dtype=float))[:, :2])
        s = self._approach(q, approach)
        phi = self.joint_angles_rad(q_deg, approach)
        p = self.params.vector
        jp, jq = jacobian_rad(p, phi)
        m = self.sheet_matrix()
        arm = forward_rad(p, phi)
        tool = self.tool
        if tool is not None:   # the tool turns with phi1 + phi2 (and q4)
            q4, s4 = self._joint4(q_deg, approach)
            ang = flange_angle_rad(p, phi) + self.joint4_rad(q_deg, approach)
            off, d_ang = tool_offset_rad(tool.tool_mm, ang)
            arm = arm + off
            for k in (2, 3):
                jp[:, :, k] += d_ang
            for k in (0, 1):
                jq[:, :, k] += d_ang
            d_ang_sheet = d_ang @ m.T
        cols = [np.einsum("ij,njk->nik", m, jp)]
        jq_sheet = np.einsum("ij,njk->nik", m, jq)
        for k, e in enumerate(self.effects):
            if isinstance(e, JointEffect) and e.joint == 4:
                if tool is None:
                    cols.append(np.zeros((len(q), 2, len(e.theta))))
                else:
                    _, dd = e.delta(q4, s4)
                    cols.append(d_ang_sheet[:, :, None] * dd[:, None, :])
            elif isinstance(e, JointEffect):
                j = e.joint - 1
                _, dd = e.delta_all(q, s) if isinstance(e, JointTerms) else e.delta(q[:, j], s[:, j])
                cols.append(jq_sheet[:, :, j][:, :, None] * dd[:, None, :])
            elif isinstance(e, Tool):
                c, sn = np.cos(ang), np.sin(ang)
                rot = np.stack([np.stack([c, -sn], -1), np.stack([sn, c], -1)], 1)  # (N,2,2)
                cols.append(np.einsum("ij,njk->nik", m, rot))
            elif isinstance(e, SheetAffine):
                # M_total = A_after @ e.M @ A_before
                before = np.eye(2)
                after = np.eye(2)
                for f in self.effects[:k]:
                    if isinstance(f, SheetAffine):
                        before = f.M @ before
                for f in self.effects[k + 1:]:
                    if isinstance(f, SheetAffine):
                        after = f.M @ after
                blocks = [np.einsum("ij,nj->ni", after @ dm @ before, arm)[:, :, None]
                          for dm in e.d_matrix()]
                cols.append(np.concatenate(blocks, axis=2) if blocks else np.zeros((len(q), 2, 0)))
            else:
                cols.append(np.zeros((len(q), 2, len(e.theta))))
        return np.concatenate(cols, axis=2)

    def param_labels(self) -> list[str]:
        labels = ["L1_mm", "L2_mm", "z1", "z2", "base_x_mm", "base_y_mm"]
        for e in self.effects:
            labels += [f"{e.label}.{n}" for n in e.param_names]
        return labels
