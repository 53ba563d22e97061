"""Planning with the tool and joint 4: position and orientation (docs/format.md, "Joint 4
and the tool").

A target's ``theta_deg`` is the tool's orientation in the sheet frame: the direction of the
flange frame's x axis, ``phi1 + phi2 + q4_real`` (the tool's direction at commanded
``q4 = 0`` is ``tool_mm``, so ``theta`` is the angle the tool frame is turned to). For each
target (mm, arm frame after undoing ``sheet_affine``):

1. the flange must be at ``F = P - Rot(theta) tool``; :func:`plan_targets` (the joint-1/2
   effects inverted by Newton's method) gives ``q1, q2`` for ``F`` with the model less its
   tool;
2. joint 4 must really turn to ``theta - (phi1 + phi2)`` (the links' real angles with
   their effects); its command inverts the joint-4 effects by Newton's method (approach
   ``approach4``), wrapped into (-180, 180];
3. the full model's forward position and orientation are checked.

Targets without ``theta`` keep ``q4`` at the given command (default 0): the tool turned
with link 2 is folded into link 2 for that ``q4`` (:func:`folded_params`), and plain
:func:`plan_targets` inverts that.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision_cal.model.kinematics import ScaraParams, flange_angle_rad
from vision_cal.model.robot import JointEffect, RobotModel, Tool
from vision_cal.model.motion import JOINT4_LIMITS_DEG, JOINT_LIMITS_DEG
from vision_cal.plan.compensate import PlannedTarget, plan_targets

#: default joint-4 range of a SCARA (commanded, deg)


@dataclass(frozen=True)
class PlannedPose:
    """A planned target with joint 4. ``target.q_deg`` holds q1, q2."""

    target: PlannedTarget
    q4_deg: float
    approach4: int
    theta_deg: float               # the orientation asked for (NaN: none asked)

    def to_row(self) -> dict:
        return dict(self.target.to_row(), q4_deg=float(self.q4_deg),
                    approach4=int(self.approach4))


def without_joint4(model: RobotModel) -> RobotModel:
    """The model less its tool and joint-4 effects (the flange's model)."""
    return RobotModel(model.params, tuple(e for e in model.effects if not isinstance(e, Tool)
                                          and not (isinstance(e, JointEffect) and e.joint == 4)))


def folded_params(params: ScaraParams, tool_mm, q4_real_deg: float) -> ScaraParams:
    """The base model with the tool folded into link 2 at a fixed real joint-4 angle:
    ``L2 e_x + Rot(q4) tool`` becomes ``L2' e_x`` turned by ``z2' - z2``."""
    a = np.radians(q4_real_deg)
    v = np.array([params.L2_mm + np.cos(a) * tool_mm[0] - np.sin(a) * tool_mm[1],
                  np.sin(a) * tool_mm[0] + np.cos(a) * tool_mm[1]])
    return ScaraParams(params.L1_mm, float(np.hypot(*v)), params.z1_deg,
                       params.z2_deg + float(np.degrees(np.arctan2(v[1], v[0]))),
                       params.base_x_mm, params.base_y_mm)


def _invert_joint4(model: RobotModel, q4_real: np.ndarray, s4: np.ndarray) -> np.ndarray:
    """Commands (N,) rad whose real joint-4 angle is ``q4_real`` (N,) rad."""
    effects = [e for e in model.effects if isinstance(e, JointEffect) and e.joint == 4]
    x, h = q4_real.copy(), 1e-7
    for _ in range(50):
        if not effects:
            break
        total, deriv = np.zeros_like(x), np.ones_like(x)
        for e in effects:
            d0 = e.delta(x, s4)[0]
            total += d0
            deriv += (e.delta(x + h, s4)[0] - d0) / h
        step = (x + total - q4_real) / deriv
        x -= step
        if np.max(np.abs(step), initial=0.0) < 1e-14:
            break
    return x


def orientation_deg(model: RobotModel, q_deg, approach=None) -> np.ndarray:
    """The tool's orientation (N,) deg in the arm frame, ``phi1 + phi2 + q4_real``, for
    joints (N, 3) and approach (N, 3)."""
    phi = model.joint_angles_rad(q_deg, approach)
    return np.degrees(flange_angle_rad(model.params.vector, phi)
                      + model.joint4_rad(q_deg, approach))


def plan_poses(model: RobotModel, ids, targets_mm, theta_deg=None, *, elbow: int = 1,
               approach=(1, 1, 1), q4_deg: float = 0.0, joint_limits_deg=JOINT_LIMITS_DEG,
               joint4_limits_deg=JOINT4_LIMITS_DEG, min_sin_q2: float = 0.05
               ) -> list[PlannedPose]:
    """Joint commands (q1, q2, q4) for targets (N, 2) mm with orientations ``theta_deg``
    (N,) deg (None: joint 4 at ``q4_deg`` for all); failures carry their reason."""
    xy = np.asarray(targets_mm, dtype=float).reshape(-1, 2)
    n = len(xy)
    s = np.broadcast_to(np.asarray(approach, dtype=float), (n, 3))
    tool = model.tool.tool_mm if model.tool is not None else (0.0, 0.0)
    flange_model = without_joint4(model)
    M = model.sheet_matrix()
    if theta_deg is None:
        # q4 fixed: its real angle depends only on the command, fold the tool into link 2
        q4r = float(np.degrees(model.joint4_rad([[0.0, 0.0, q4_deg]], [s[0]])[0]))
        folded = RobotModel(folded_params(model.params, tool, q4r), flange_model.effects)
        planned = plan_targets(folded, ids, xy, elbow=elbow, approach=tuple(s[0, :2]),
                               joint_limits_deg=joint_limits_deg, min_sin_q2=min_sin_q2)
        return [PlannedPose(p, q4_deg, int(s[0, 2]), float("nan")) for p in planned]
    theta = np.radians(np.broadcast_to(np.asarray(theta_deg, dtype=float), (n,)))
    arm = xy @ np.linalg.inv(M).T
    rot_tool = np.column_stack([np.cos(theta) * tool[0] - np.sin(theta) * tool[1],
                                np.sin(theta) * tool[0] + np.cos(theta) * tool[1]])
    flange_sheet = (arm - rot_tool) @ M.T
    planned = plan_targets(flange_model, ids, flange_sheet, elbow=elbow,
                           approach=tuple(s[0, :2]), joint_limits_deg=joint_limits_deg,
                           min_sin_q2=min_sin_q2)
    out = []
    lo4, hi4 = joint4_limits_deg
    for i, p in enumerate(planned):
        if p.status != "ok" and p.q_deg is None:
            out.append(PlannedPose(p, float("nan"), int(s[i, 2]), float(np.degrees(theta[i]))))
            continue
        q12 = np.array([p.q_deg])
        phi = model.joint_angles_rad(q12, [s[i, :2]])
        need = theta[i] - flange_angle_rad(model.params.vector, phi)
        need = (need + np.pi) % (2 * np.pi) - np.pi
        q4 = float(np.degrees(_invert_joint4(model, need, s[i:i + 1, 2])[0]))
        q3 = np.array([[*p.q_deg, q4]])
        pos = model.predict(q3, s[i:i + 1])[0]
        res = float(np.hypot(*(pos - xy[i])))
        ang = float(orientation_deg(model, q3, s[i:i + 1])[0]) - float(np.degrees(theta[i]))
        ang = (ang + 180.0) % 360.0 - 180.0
        reason = p.reason
        if not reason and not lo4 <= q4 <= hi4:
            reason = f"joint 4 at {q4:.3f} deg is outside its limits [{lo4:g}, {hi4:g}]"
        if not reason and not (res <= 1e-6 and abs(ang) <= 1e-6):
            reason = f"the model could not be inverted (residual {res:.2g} mm, {ang:.2g} deg)"
        t = PlannedTarget(p.id, tuple(xy[i]), p.q_deg, p.approach,
                          "failed" if reason else "ok", reason, res)
        out.append(PlannedPose(t, q4, int(s[i, 2]), float(np.degrees(theta[i]))))
    return out


def controller_tool_mm(params: ScaraParams, tool_mm) -> tuple[float, float]:
    """The tool in the controller's tool-0 frame (x along link 2 at J4 = 0 as the
    controller counts it, i.e. without the calibrated z2): ``Rot(z2) tool_mm``. What a
    SPEL+ ``TLSet`` takes (:func:`vision_cal.program.spel.tlset_line`)."""
    a = np.radians(params.z2_deg)
    return (float(np.cos(a) * tool_mm[0] - np.sin(a) * tool_mm[1]),
            float(np.sin(a) * tool_mm[0] + np.cos(a) * tool_mm[1]))


def unfold_params(folded: ScaraParams, tool_mm, q4_real_deg: float = 0.0) -> ScaraParams:
    """The inverse of :func:`folded_params`: the link-2 model whose link plus the tool at
    real joint-4 angle ``q4_real_deg`` is ``folded``'s link 2 (a model calibrated with
    every mark at one ``j4_deg``, and a rough ``tool_mm``)."""
    a = np.radians(q4_real_deg)
    t = np.array([np.cos(a) * tool_mm[0] - np.sin(a) * tool_mm[1],
                  np.sin(a) * tool_mm[0] + np.cos(a) * tool_mm[1]])
    along = np.sqrt(folded.L2_mm**2 - t[1]**2)
    return ScaraParams(folded.L1_mm, float(along - t[0]), folded.z1_deg,
                       folded.z2_deg - float(np.degrees(np.arctan2(t[1], along))),
                       folded.base_x_mm, folded.base_y_mm)
