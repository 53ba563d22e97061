import numpy as np
import pytest

from vision_cal.errors import VisionCalError
from vision_cal.model.kinematics import ScaraParams, forward
from vision_cal.model.robot import (JointBacklash, JointCyclic, JointScale, RobotModel, SheetAffine,
                              effect_from_json)

P = ScaraParams(344.05, 259.87, -2.57, -8.13, -424.26, -230.35)


def test_base_model_equals_kinematics():
    q = np.random.default_rng(0).uniform(-90, 90, (10, 2))
    np.testing.assert_allclose(RobotModel(P).predict(q), forward(P, q), atol=1e-12)


def test_backlash_lags_against_approach():
    m = RobotModel(P, (JointBacklash(joint=2, deg=0.2),))
    q = np.array([[10.0, 30.0], [10.0, 30.0]])
    phi = np.degrees(m.joint_angles_rad(q, [[1, 1], [1, -1]]))
    np.testing.assert_allclose(phi[:, 1], [30.0 - 0.1, 30.0 + 0.1])
    np.testing.assert_allclose(phi[:, 0], [10.0, 10.0])


def test_scale_and_cyclic_follow_their_definitions():
    q = np.array([[40.0, -70.0]])
    m = RobotModel(P, (JointScale(joint=1, scale=0.003),
                       JointCyclic(joint=2, harmonic=2, deg=0.05, phase_deg=30.0)))
    phi = np.degrees(m.joint_angles_rad(q))
    assert phi[0, 0] == pytest.approx(40.0 * 1.003)
    assert phi[0, 1] == pytest.approx(-70.0 + 0.05 * np.sin(np.radians(2 * -70.0 + 30.0)))


def test_full_jacobian_matches_finite_differences():
    m = RobotModel(P, (JointBacklash(joint=2, deg=0.1), JointScale(joint=1, scale=0.002),
                       JointCyclic(joint=2, harmonic=1, deg=0.05, phase_deg=10.0),
                       SheetAffine(((1.002, 0.0), (0.0, 1.0)), dof="x"),
                       SheetAffine(((1.0, 0.001), (0.001, 1.0)), dof="shear")))
    rng = np.random.default_rng(1)
    q, s = rng.uniform(-120, 120, (15, 2)), rng.choice([-1, 1], (15, 2))
    J, v = m.jacobian(q, s), m.vector
    for k in range(len(v)):
        d = np.zeros_like(v)
        d[k] = 1e-7
        num = (m.with_vector(v + d).predict(q, s) - m.with_vector(v - d).predict(q, s)) / 2e-7
        np.testing.assert_allclose(J[:, :, k], num, atol=2e-5, err_msg=m.param_labels()[k])


def test_effect_json_round_trip_and_errors():
    e = JointCyclic(joint=1, harmonic=2, deg=0.07, phase_deg=-40.0)
    back = effect_from_json(e.to_json())
    assert back.deg == pytest.approx(0.07) and back.phase_deg == pytest.approx(-40.0)
    with pytest.raises(VisionCalError, match="joint must be 1 or 2"):
        effect_from_json({"name": "joint_backlash", "joint": 3, "deg": 0.1})
    with pytest.raises(VisionCalError, match="harmonic must be 1 or 2"):
        effect_from_json({"name": "joint_cyclic", "joint": 1, "harmonic": 3, "deg": 0.1})
