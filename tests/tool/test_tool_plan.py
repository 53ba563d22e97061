"""Planning position and orientation with the calibrated tool and joint 4: the commands
hit the targets on the world's true robot within the calibration's predicted error."""

import numpy as np

from tests.tool.oracle import tool_angle_deg
from vision_cal.model.tool_fit import fit_tool
from vision_cal.model.robot import JointBacklash, JointScale, RobotModel, Tool
from vision_cal.model.kinematics import ScaraParams
from vision_cal.plan.orient import folded_params, plan_poses
from vision_cal.world.truth_model import TrueRobot


def test_folded_params_by_hand():
    p = folded_params(ScaraParams(300.0, 200.0), (30.0, 0.0), 90.0)
    # link 2 plus the tool turned 90 deg: (200, 30)
    np.testing.assert_allclose([p.L2_mm, p.z2_deg], [np.hypot(200, 30),
                                                    np.degrees(np.arctan2(30, 200))])


def test_plan_without_theta_keeps_q4_and_hits():
    m = RobotModel(ScaraParams(300.0, 200.0, 3.0, -2.0, 10.0, 5.0), (Tool(tool_mm=(25.0, 7.0)),
                   JointScale(joint=4, scale=0.01)))
    (p,) = plan_poses(m, ["a"], [[250.0, 260.0]], q4_deg=40.0)
    q = [[*p.target.q_deg, 40.0]]
    np.testing.assert_allclose(m.predict(q)[0], [250.0, 260.0], atol=1e-9)


def test_compensated_plan_with_orientation_on_the_true_robot():
    truth = TrueRobot.from_json(
        {"L1_mm": 344.05, "L2_mm": 259.87, "joint_zero_deg": [-2.57, -8.13],
         "base_mm": [-424.26, -230.35], "tool_mm": [27.5, -11.0]},
        [{"name": "joint_scale", "joint": 4, "scale": 0.004},
         {"name": "joint_backlash", "joint": 4, "deg": 0.1}])
    rng = np.random.default_rng(77)
    n = 48
    q = np.column_stack([rng.uniform(0, 110, n), rng.uniform(-120, -30, n),
                         rng.uniform(-170, 170, n)])
    s = np.where(rng.random((n, 3)) < 0.5, -1.0, 1.0)
    s[:, :2] = 1.0
    xy = truth.pen_mm(q, s) + rng.normal(0.0, 0.01, (n, 2))
    f = fit_tool(q[:, :2], q[:, 2], xy, approach=s,
                 effects=(JointScale(joint=4), JointBacklash(joint=4)))
    targets = np.column_stack([rng.uniform(-250, -50, 10), rng.uniform(-50, 150, 10)])
    theta = rng.uniform(-180, 180, 10)
    plan = plan_poses(f.fit.model, [f"t{i}" for i in range(10)], targets, theta)
    assert all(p.target.status == "ok" for p in plan)
    qp = np.array([[*p.target.q_deg, p.q4_deg] for p in plan])
    sp = np.ones((10, 3))
    pos_err = np.hypot(*(truth.pen_mm(qp, sp) - targets).T)
    ang_err = (tool_angle_deg(truth, qp, sp) - theta + 180) % 360 - 180
    # 10 um mark noise over 48 marks: the model is good to a few um and millidegrees
    assert pos_err.max() < 0.03, pos_err
    assert np.abs(ang_err).max() < 0.05, ang_err
    # the plan is wrong without the tool: a broken planner cannot pass the bound above
    nominal = plan_poses(RobotModel(f.fit.params), ["x"], targets[:1], theta[:1])
    qn = np.array([[*nominal[0].target.q_deg, nominal[0].q4_deg]])
    assert np.hypot(*(truth.pen_mm(qn, sp[:1]) - targets[:1]).T)[0] > 1.0
