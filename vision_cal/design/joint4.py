"""Planning joint-4 turns for a calibration (an off-axis tool, docs/format.md "Joint 4 and
the tool").

:func:`turn_joint4` takes a plan made with a model whose tool is folded into link 2 (a
pilot calibration at one ``j4_deg``, or the nominal model) and turns joint 4 over
``j4_values`` (cycled over the marks, so each sheet region sees several tool directions),
re-solving joints 1 and 2 so each mark stays on the sheet point the plan chose (with the
rough ``tool_mm`` of the robot file: marks land within a few millimetres of it, clear of
markers as the plan kept them). The via points keep each joint's planned approach. A mark
no turned tool can keep on its point stays as planned (at ``folded_j4_deg``).
"""

from __future__ import annotations

import numpy as np

from vision_cal.errors import VisionCalError
from vision_cal.kinematics import ScaraParams, forward
from vision_cal.model import RobotModel, Tool
from vision_cal.plan.calibration_plan import PlannedMark
from vision_cal.plan.orient import plan_poses, unfold_params

#: joint-4 angles cycled over the marks: six tool directions 60 deg apart
J4_VALUES_DEG = (-150.0, -90.0, -30.0, 30.0, 90.0, 150.0)


def turn_joint4(plan, folded: ScaraParams, tool_mm, *, j4_values=J4_VALUES_DEG,
                overshoot_deg: float = 3.0, folded_j4_deg: float = 0.0
                ) -> tuple[list[PlannedMark], dict[str, float]]:
    """(new plan, mark id -> j4_deg): the same sheet points with joint 4 turned.
    ``folded_j4_deg``: the joint-4 angle at which ``folded`` was calibrated."""
    if np.hypot(*tool_mm) == 0:
        raise VisionCalError("the tool is on the joint-4 axis (tool_mm = [0, 0]): turning "
                             "joint 4 moves no mark; give the robot file's tool_mm",
                             field="tool_mm")
    model = RobotModel(unfold_params(folded, tool_mm, folded_j4_deg),
                       (Tool(tool_mm=tuple(tool_mm)),))
    out, j4 = [], {}
    for i, m in enumerate(plan):
        xy = forward(folded, [m.joints_deg])
        elbow = 1 if np.sin(np.radians(m.joints_deg[1] + folded.z2_deg)) > 0 else -1
        # the cycle's next angle, else the following ones (a point near the edge of the
        # reach may not be kept with the tool turned outward), else joint 4 at 0
        p = None
        for k in range(len(j4_values)):
            a = float(j4_values[(i + k) % len(j4_values)])
            (p,) = plan_poses(model, [m.id], xy, q4_deg=a, elbow=elbow,
                              approach=(*m.approach, 1))
            if p.target.status == "ok":
                break
        if p is None or p.target.status != "ok":
            out.append(m)
            j4[m.id] = float(folded_j4_deg)
            continue
        q = np.asarray(p.target.q_deg)
        via = q - np.asarray(m.approach, dtype=float) * overshoot_deg
        out.append(PlannedMark(m.id, (float(q[0]), float(q[1])), m.role, tuple(m.approach),
                               ((float(via[0]), float(via[1])),)))
        j4[m.id] = a
    return out, j4
