"""The tool offset and joint 4 from marks (contract "Joint 4 and the tool", docs/format.md).

Two methods, as for the base model:

- :func:`vision_cal.model.tool_fit.fit_tool` - least squares: ``tool_mm`` (and joint-4
  effects, when asked) jointly with the base parameters and any other effect, through
  :class:`vision_cal.model.lsq.Fit` on joints ``[q1, q2, q4]``; std and correlations from
  its covariance (in model/: identify/'s first guess of the tool uses it too).
- :func:`paper_tool` - the seed paper's circle method extended to joint 4: marks drawn at
  one joint-1/joint-2 pose and three or more joint-4 angles lie on a circle whose centre
  is the flange (the joint-4 axis) and whose radius is ``|tool|``. With the paper's base
  circle and elbow circle drawn at one joint-4 angle ``q4c`` (there the tool is folded
  into L2 and z2), the elbow of the joint-4 group's pose is ``base + L1 Rot(q1 + z1)``,
  and::

      L2      = |flange - elbow|
      z2      = atan2(flange - elbow) - (q1 + z1) - q2
      tool    = |tool| Rot(a) [1, 0],  a = circular mean of atan2(pen_i - flange)
                                           - (q1 + z1 + q2 + z2) - q4_i

When every mark has the same ``j4_deg`` the tool cannot be told from link 2:
:func:`vision_cal.model.tool_fit.folded_statement` says so, and what marks would separate it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision_cal.estimate.circles import Circle
from vision_cal.estimate.paper import paper_method
from vision_cal.errors import CalibrationError
from vision_cal.model.kinematics import ScaraParams
from vision_cal.model.robot import RobotModel, Tool
from vision_cal.model.tool_fit import joint4_values


@dataclass(frozen=True)
class PaperTool:
    """The circle method on joint 4: the base model with the tool separated."""

    params: ScaraParams
    tool_mm: tuple[float, float]
    circle_joint4: Circle
    folded_q4_deg: float            # the joint-4 angle of the base and elbow circles

    @property
    def model(self) -> RobotModel:
        return RobotModel(self.params, (Tool(tool_mm=self.tool_mm),))

    def to_json(self) -> dict:
        return {"identified": True, "tool_mm": list(self.tool_mm),
                "radius_mm": float(np.hypot(*self.tool_mm)),
                "circle_joint4": self.circle_joint4.to_json(),
                "folded_q4_deg": self.folded_q4_deg}


def _joint4_group(q: np.ndarray, q4: np.ndarray) -> np.ndarray:
    """Indices of the largest group of marks at one (q1, q2) with >= 3 distinct q4."""
    key = np.round(q, 6)
    best = np.zeros(0, dtype=int)
    for k in np.unique(key, axis=0):
        idx = np.flatnonzero(np.all(key == k, axis=1))
        if len(joint4_values(q4[idx])) >= 3 and len(idx) > len(best):
            best = idx
    return best


def paper_tool(q_deg, q4_deg, xy_mm) -> PaperTool:
    """The circle method with joint 4 (module docstring): marks (N, 2) sheet mm at joints
    (N, 2) and joint 4 (N,) deg."""
    q = np.asarray(q_deg, dtype=float).reshape(-1, 2)
    q4 = np.broadcast_to(np.asarray(q4_deg, dtype=float), (len(q),))
    p = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
    g4 = _joint4_group(q, q4)
    if len(g4) == 0:
        raise CalibrationError("the circle method on joint 4 needs 3 marks at one joint-1/"
                               "joint-2 pose and three j4_deg values (the joint-4 circle): "
                               "none found")
    values, counts = np.unique(np.round(q4, 6), return_counts=True)
    q4c = float(values[np.argmax(counts)])
    base_marks = np.flatnonzero(np.abs(q4 - q4c) <= 1e-6)
    base = paper_method(q[base_marks], p[base_marks]).or_raise().params  # tool folded at q4c
    c4 = Circle.from_estimate(p[g4]).or_raise()
    flange = np.array(c4.center_mm)
    phi1 = np.radians(q[g4[0], 0] + base.z1_deg)
    elbow = np.array(base.base_mm) + base.L1_mm * np.array([np.cos(phi1), np.sin(phi1)])
    d = flange - elbow
    phi12 = np.arctan2(d[1], d[0])
    z2 = (phi12 - phi1 - np.radians(q[g4[0], 1]) + np.pi) % (2 * np.pi) - np.pi
    a = np.arctan2(p[g4, 1] - flange[1], p[g4, 0] - flange[0]) - phi12 - np.radians(q4[g4])
    a_mean = float(np.arctan2(np.mean(np.sin(a)), np.mean(np.cos(a))))
    tool = (c4.radius_mm * np.cos(a_mean), c4.radius_mm * np.sin(a_mean))
    params = ScaraParams(base.L1_mm, float(np.hypot(*d)), base.z1_deg, float(np.degrees(z2)),
                         base.base_x_mm, base.base_y_mm)
    return PaperTool(params, (float(tool[0]), float(tool[1])), c4, q4c)
