"""The compensated planner: sheet targets -> joint commands that hit them.

For each target the calibrated model (every effect it found included) is inverted:

1. the sheet matrix (``sheet_affine``) is undone, then the base model's inverse
   kinematics gives the angle each joint must *really* turn to (elbow by choice);
2. each joint's command is found from its effects by Newton's method on
   ``q + sum(delta_k(q, s)) = phi`` - backlash adds ``s * band / 2`` for the chosen
   approach ``s``, gear scale and cyclic errors are inverted numerically;
3. the command is checked by the forward model (residual below 1e-6 mm) and against the
   joint limits.

The planner chooses the approach (default +1 for both joints: each joint comes onto its
angle turning counter-clockwise) and its trajectory must honour it: overshoot via points
on the other side. A target out of reach, outside the joint limits or too close to the
singularity is reported with the reason; the others are still planned.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision_cal.model.kinematics import ik_failures, inverse
from vision_cal.model.robot import JointEffect, JointTerms, RobotModel
from vision_cal.model.motion import JOINT_LIMITS_DEG, TRAJECTORY_DT_S
from vision_cal.plan.calibration_plan import PlannedMark
from vision_cal.plan.trajectory import plan_trajectory, write_trajectory_csv


@dataclass(frozen=True)
class PlannedTarget:
    id: str
    target_mm: tuple[float, float]
    q_deg: tuple[float, float] | None
    approach: tuple[int, int]
    status: str = "ok"            # "ok" | "failed"
    reason: str = ""
    residual_mm: float = float("nan")  # forward model of the command minus the target

    def to_row(self) -> dict:
        q = self.q_deg if self.q_deg is not None else (float("nan"), float("nan"))
        return {"id": self.id, "q1_deg": float(q[0]), "q2_deg": float(q[1]),
                "approach1": int(self.approach[0]), "approach2": int(self.approach[1]),
                "status": self.status, "reason": self.reason}


def _invert_joints(model: RobotModel, phi_deg: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Commands (N, 2) deg whose effective joint angles are ``phi_deg`` (N, 2), for the
    approach signs ``s`` (N, 2): Newton's method on every target at once."""
    q = np.radians(phi_deg).copy()
    phi = np.radians(phi_deg)
    for j in range(2):
        effects = [e for e in model.effects if isinstance(e, JointEffect) and e.joint == j + 1
                   and not isinstance(e, JointTerms)]
        if not effects:
            continue
        x, sj, h = q[:, j].copy(), s[:, j], 1e-7
        for _ in range(50):
            total = np.zeros_like(x)
            deriv = np.ones_like(x)
            for e in effects:
                d0 = e.delta(x, sj)[0]
                total += d0
                deriv += (e.delta(x + h, sj)[0] - d0) / h
            step = (x + total - phi[:, j]) / deriv
            x -= step
            if np.nanmax(np.abs(step), initial=0.0) < 1e-14:
                break
        q[:, j] = x
    if any(isinstance(e, JointTerms) for e in model.effects):
        # joint_terms couple the joints: Newton on both at once (2x2 numeric Jacobian)
        qd, h = np.degrees(q), 1e-6
        for _ in range(50):
            err = model.joint_angles_rad(qd, s) - phi                          # (N, 2)
            J = np.stack([(model.joint_angles_rad(qd + h * np.eye(2)[k], s)
                           - model.joint_angles_rad(qd, s)) / h for k in range(2)], axis=2)
            step = np.linalg.solve(J, err[..., None])[..., 0]
            qd = qd - step
            if np.nanmax(np.abs(step), initial=0.0) < 1e-12:
                break
        return qd
    return np.degrees(q)


def plan_targets(model: RobotModel, ids, targets_mm, *, elbow: int = 1, approach=(1, 1),
                 joint_limits_deg=JOINT_LIMITS_DEG, min_sin_q2: float = 0.05
                 ) -> list[PlannedTarget]:
    """Joint commands for every target (N, 2) mm; failures carry their reason."""
    xy = np.asarray(targets_mm, dtype=float).reshape(-1, 2)
    n = len(xy)
    s = np.broadcast_to(np.asarray(approach, dtype=float), (n, 2))
    arm = xy @ np.linalg.inv(model.sheet_matrix()).T
    phi = inverse(model.params, arm, elbow=elbow, min_sin_q2=min_sin_q2, on_fail="nan")
    unreachable = np.isnan(phi).any(axis=1)
    q = _invert_joints(model, np.where(unreachable[:, None], 0.0, phi), s)
    lim = np.asarray(joint_limits_deg, dtype=float)
    res = np.hypot(*(model.predict(q, s) - xy).T)
    reasons = [""] * n
    why_ik = ik_failures(model.params, arm, min_sin_q2=min_sin_q2) if unreachable.any() else []
    for i in range(n):
        if unreachable[i]:
            reasons[i] = "target " + why_ik[i]
            continue
        for j in range(2):
            if not lim[j, 0] <= q[i, j] <= lim[j, 1]:
                reasons[i] = (f"joint {j + 1} at {q[i, j]:.3f} deg is outside its limits "
                              f"[{lim[j, 0]:g}, {lim[j, 1]:g}]")
                break
        if not reasons[i] and not res[i] <= 1e-6:
            reasons[i] = f"the model could not be inverted (residual {res[i]:.2g} mm)"
    out = []
    for i, tid in enumerate(ids):
        sig = (int(s[i, 0]), int(s[i, 1]))
        if unreachable[i]:
            out.append(PlannedTarget(tid, tuple(xy[i]), None, sig, "failed", reasons[i]))
        else:
            out.append(PlannedTarget(tid, tuple(xy[i]), (float(q[i, 0]), float(q[i, 1])), sig,
                                     "failed" if reasons[i] else "ok", reasons[i],
                                     float(res[i])))
    return out


def to_planned_marks(planned: list[PlannedTarget], *, overshoot_deg: float = 3.0,
                     role: str = "validation") -> list[PlannedMark]:
    """Planned targets as marks to draw: each joint passes a via point ``overshoot_deg``
    short of its angle on the approach side, so its last motion has the planned sign."""
    out = []
    for p in planned:
        if p.status != "ok":
            continue
        q = np.asarray(p.q_deg)
        via = q - np.asarray(p.approach, dtype=float) * overshoot_deg
        out.append(PlannedMark(p.id, (float(q[0]), float(q[1])), role,
                               (int(p.approach[0]), int(p.approach[1])),
                               ((float(via[0]), float(via[1])),)))
    return out


def write_plan_trajectory(path, planned: list[PlannedTarget], *, home_deg=(0.0, 0.0),
                          dt_s: float = TRAJECTORY_DT_S):
    """The joint-space reference trajectory through the planned points (CSV)."""
    traj = plan_trajectory(to_planned_marks(planned), home_deg=home_deg, dt_s=dt_s)
    return write_trajectory_csv(path, traj)
