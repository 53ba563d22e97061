"""The tool and joint 4 in the estimator's model (contract "Joint 4 and the tool"):
hand-computed anchors (direction and sign of q4) and the analytic Jacobian."""

import numpy as np
import pytest

from vision_cal.model.kinematics import ScaraParams, forward, forward_tool
from vision_cal.model.robot import JointBacklash, JointScale, RobotModel, Tool, effect_from_json

P = ScaraParams(300.0, 200.0)


@pytest.mark.parametrize("q, q4, tool, pen", [
    ((0, 0), 0, (30, 0), (530, 0)),        # tool along link 2
    ((0, 0), 90, (30, 0), (500, 30)),      # q4 > 0 turns the tool counter-clockwise
    ((0, 0), -90, (30, 0), (500, -30)),
    ((90, 0), 0, (30, 0), (0, 530)),       # joint 1 carries the tool
    ((0, 90), 0, (0, 10), (290, 200)),     # link 2 along +y, tool's y is to its left
])
def test_tool_anchors(q, q4, tool, pen):
    np.testing.assert_allclose(forward_tool(P, [q], q4, tool)[0], pen, atol=1e-9)
    m = RobotModel(P, (Tool(tool_mm=tool),))
    np.testing.assert_allclose(m.predict([[*q, q4]])[0], pen, atol=1e-9)


def test_no_tool_is_the_old_model():
    q = np.array([[10.0, -40.0], [70.0, 20.0]])
    m = RobotModel(P, (JointBacklash(joint=2, deg=0.1),))
    q3 = np.column_stack([q, [33.0, -50.0]])
    np.testing.assert_array_equal(m.predict(q3), m.predict(q))
    np.testing.assert_array_equal(forward_tool(P, q, 25.0), forward(P, q))
    assert RobotModel(P, (Tool(),)).predict(q3).tolist() == forward(P, q).tolist()


def test_joint4_effects_act_on_q4():
    tool = (40.0, 0.0)
    m = RobotModel(P, (Tool(tool_mm=tool), JointScale(joint=4, scale=0.01),
                       JointBacklash(joint=4, deg=0.2)))
    q = [[0.0, 0.0, 90.0]]
    # q4 real = 90 * 1.01 - (+1) * 0.1 deg
    a = np.radians(90 * 1.01 - 0.1)
    np.testing.assert_allclose(m.predict(q, [[1, 1, 1]])[0],
                               [500 + 40 * np.cos(a), 40 * np.sin(a)], atol=1e-9)
    a = np.radians(90 * 1.01 + 0.1)
    np.testing.assert_allclose(m.predict(q, [[1, 1, -1]])[0],
                               [500 + 40 * np.cos(a), 40 * np.sin(a)], atol=1e-9)
    assert effect_from_json({"name": "joint_scale", "joint": 4, "scale": 0.01}).joint == 4


def test_jacobian_matches_finite_differences():
    rng = np.random.default_rng(3)
    p = ScaraParams(310.0, 190.0, 5.0, -3.0, 12.0, -7.0)
    m = RobotModel(p, (Tool(tool_mm=(25.0, -8.0)), JointScale(joint=4, scale=0.002),
                       JointBacklash(joint=1, deg=0.05), JointScale(joint=2, scale=0.001)))
    q = np.column_stack([rng.uniform(-90, 90, (12, 2)), rng.uniform(-170, 170, 12)])
    s = np.where(rng.random((12, 3)) < 0.5, -1.0, 1.0)
    J = m.jacobian(q, s)
    v = m.vector
    num = np.empty_like(J)
    for k in range(len(v)):
        h = np.zeros_like(v)
        h[k] = 1e-6
        num[:, :, k] = (m.with_vector(v + h).predict(q, s)
                        - m.with_vector(v - h).predict(q, s)) / 2e-6
    np.testing.assert_allclose(J, num, atol=1e-5)


def test_joint_columns_turn_the_tool():
    """A joint-1/2 error turns the tool with the link (the diagnosis's columns): the
    columns are the pen's derivative with respect to each commanded joint (no effects)."""
    m = RobotModel(P, (Tool(tool_mm=(25.0, -15.0)), JointScale(joint=4, scale=0.002)))
    q = np.array([[10.0, -40.0, 70.0], [70.0, 20.0, -120.0]])
    h = 1e-4
    cols = m.joint_columns(q)
    for j in range(2):
        d = np.zeros(3)
        d[j] = h
        num = (m.predict(q + d) - m.predict(q - d)) / np.radians(2 * h)
        np.testing.assert_allclose(cols[:, :, j], num, atol=1e-6)
    # without the tool term the column would miss the tool's own swing (25-30 mm lever)
    bare = RobotModel(P).joint_columns(q[:, :2])
    assert np.max(np.abs(cols - bare)) > 10.0
