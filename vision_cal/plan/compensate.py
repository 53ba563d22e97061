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

from vision_cal.errors import VisionCalError
from vision_cal.kinematics import inverse
from vision_cal.model import JointEffect, RobotModel
from vision_cal.plan.calibration_plan import PlannedMark

DEFAULT_LIMITS_DEG = ((-170.0, 170.0), (-150.0, 150.0))


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


def _invert_joint(model: RobotModel, j: int, phi_rad: float, s: float) -> float:
    """Command q (rad) whose effective angle is ``phi_rad`` for joint ``j`` (0-based)."""
    effects = [e for e in model.effects if isinstance(e, JointEffect) and e.joint == j + 1]
    if not effects:
        return phi_rad
    q = phi_rad
    sv = np.array([s])
    for _ in range(50):
        total, deriv = 0.0, 1.0
        h = 1e-7
        for e in effects:
            d0 = e.delta(np.array([q]), sv)[0][0]
            d1 = e.delta(np.array([q + h]), sv)[0][0]
            total += d0
            deriv += (d1 - d0) / h
        f = q + total - phi_rad
        step = f / deriv
        q -= step
        if abs(step) < 1e-14:
            break
    return float(q)


def plan_targets(model: RobotModel, ids, targets_mm, *, elbow: int = 1, approach=(1, 1),
                 joint_limits_deg=DEFAULT_LIMITS_DEG, min_sin_q2: float = 0.05
                 ) -> list[PlannedTarget]:
    """Joint commands for every target (N, 2) mm; failures carry their reason."""
    xy = np.asarray(targets_mm, dtype=float).reshape(-1, 2)
    s = np.array(approach, dtype=float)
    minv = np.linalg.inv(model.sheet_matrix())
    out = []
    for tid, t in zip(ids, xy):
        arm = minv @ t
        try:
            phi = inverse(model.params, arm[None], elbow=elbow, min_sin_q2=min_sin_q2)[0]
        except VisionCalError as e:
            out.append(PlannedTarget(tid, tuple(t), None, tuple(int(v) for v in s), "failed",
                                     e.reason.replace("point 0 ", "target ")))
            continue
        q = np.array([np.degrees(_invert_joint(model, j, np.radians(phi[j]), s[j]))
                      for j in range(2)])
        reason = ""
        for j in range(2):
            lo, hi = joint_limits_deg[j]
            if not lo <= q[j] <= hi:
                reason = f"joint {j + 1} at {q[j]:.3f} deg is outside its limits [{lo}, {hi}]"
                break
        res = float(np.hypot(*(model.predict(q[None], s[None])[0] - t)))
        if not reason and res > 1e-6:
            reason = f"the model could not be inverted (residual {res:.2g} mm)"
        out.append(PlannedTarget(tid, tuple(t), tuple(q), tuple(int(v) for v in s),
                                 "failed" if reason else "ok", reason, res))
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
                          dt_s: float = 0.016):
    """The joint-space reference trajectory through the planned points (CSV)."""
    from vision_cal.plan.trajectory import plan_trajectory, write_trajectory_csv

    traj = plan_trajectory(to_planned_marks(planned), home_deg=home_deg, dt_s=dt_s)
    return write_trajectory_csv(path, traj)
