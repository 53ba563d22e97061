"""design: joint-4 turns that keep each planned mark on its sheet point."""

import numpy as np

from vision_cal.design.joint4 import turn_joint4
from vision_cal.kinematics import ScaraParams, forward
from vision_cal.plan.calibration_plan import PlannedMark
from vision_cal.plan.orient import folded_params
from vision_cal.render.truth_model import TrueRobot

TRUE = {"L1_mm": 344.05, "L2_mm": 259.87, "joint_zero_deg": [-2.57, -8.13],
        "base_mm": [-424.26, -230.35], "tool_mm": [21.0, -7.0]}


def test_turned_marks_stay_on_their_points():
    truth = TrueRobot.from_json(TRUE)
    # what a pilot at j4 = 0 calibrates: the tool folded into link 2
    folded = folded_params(ScaraParams(344.05, 259.87, -2.57, -8.13, -424.26, -230.35),
                           TRUE["tool_mm"], 0.0)
    plan = [PlannedMark(f"c{i}", (a, b), approach=(1, -1), via_deg=((a - 3, b + 3),))
            for i, (a, b) in enumerate([(20, -60), (45, -90), (70, -40), (30, -110)])]
    turned, j4 = turn_joint4(plan, folded, TRUE["tool_mm"])
    assert len(set(j4.values())) == 4          # four different tool directions
    q = np.array([[*m.joints_deg, j4[m.id]] for m in turned])
    np.testing.assert_allclose(truth.pen_mm(q), forward(folded, [m.joints_deg for m in plan]),
                               atol=1e-6)
    assert all(m.approach == (1, -1) for m in turned)
    # the via points keep each joint's approach side
    for m in turned:
        assert np.all(np.sign(np.subtract(m.joints_deg, m.via_deg[0])) == (1, -1))
