"""tool_mm from marks: the circle method on joint 4 against a hand computation, and the
least-squares recovery of tool_mm and joint-4 effects within 4 reported std."""

import numpy as np
import pytest

from vision_cal.model.tool_fit import fit_tool, folded_statement
from vision_cal.estimate.tool import paper_tool
from vision_cal.errors import CalibrationError
from vision_cal.model.robot import JointBacklash, JointScale
from vision_cal.world.truth_model import TrueRobot


def _r(deg, r):
    a = np.radians(deg)
    return np.array([r * np.cos(a), r * np.sin(a)])


def test_paper_circle_on_joint4_by_hand():
    # base at 0, L1 = 300, L2 = 200, zeros 0, tool (30, 0): at q4 = 0 the pen is 230 mm
    # along link 2 (tool folded), so the base circle (q2 = 0) has radius 530 and the
    # elbow circle (q1 = 0) centre (300, 0) radius 230
    q = [[0, 0], [30, 0], [60, 0], [0, -30], [0, 30]]
    xy = [_r(0, 530), _r(30, 530), _r(60, 530), (300, 0) + _r(-30, 230), (300, 0) + _r(30, 230)]
    q4 = [0, 0, 0, 0, 0]
    # joint-4 circle at q = (0, 90): flange (300, 200); pen = flange + Rot(90 + q4) (30, 0)
    q += [[0, 90]] * 3
    q4 += [0, 90, 180]
    xy += [(300, 230), (270, 200), (300, 170)]
    r = paper_tool(q, q4, np.array(xy, float))
    np.testing.assert_allclose(r.circle_joint4.center_mm, (300, 200), atol=1e-9)
    np.testing.assert_allclose(r.tool_mm, (30, 0), atol=1e-9)
    np.testing.assert_allclose([r.params.L1_mm, r.params.L2_mm, r.params.z1_deg,
                                r.params.z2_deg], [300, 200, 0, 0], atol=1e-9)
    np.testing.assert_allclose(r.model.predict(np.column_stack([q, q4])), xy, atol=1e-9)


def test_one_j4_is_folded_not_fitted():
    r = fit_tool([[0, 10], [20, 30], [40, -50], [60, 20]], 15.0, np.zeros((4, 2)))
    assert not r and "folded into L2 and z2" in r.reason
    with pytest.raises(CalibrationError, match="folded into L2 and z2"):
        r.or_raise()
    assert folded_statement([15.0, 15.0])["identified"] is False


def test_lsq_recovers_tool_and_joint4_effects_within_4_std():
    rng = np.random.default_rng(2024)
    truth = TrueRobot.from_json(
        {"L1_mm": 344.05, "L2_mm": 259.87, "joint_zero_deg": [-2.57, -8.13],
         "base_mm": [-424.26, -230.35], "tool_mm": [24.3, 9.1]},
        [{"name": "joint_scale", "joint": 4, "scale": 0.003},
         {"name": "joint_backlash", "joint": 4, "deg": 0.12}])
    n = 40
    q = np.column_stack([rng.uniform(0, 110, n), rng.uniform(-120, -30, n),
                         rng.uniform(-150, 150, n)])
    s = np.where(rng.random((n, 3)) < 0.5, -1.0, 1.0)
    xy = truth.pen_mm(q, s) + rng.normal(0.0, 0.01, (n, 2))
    f = fit_tool(q[:, :2], q[:, 2], xy, approach=s,
                 effects=(JointScale(joint=4), JointBacklash(joint=4)))
    assert np.all(np.abs(f.tool_mm - (24.3, 9.1)) < 4 * f.tool_std_mm)
    scale, band = f.joint4_effects
    assert abs(scale.scale - 0.003) < 4 * f.effect_std(scale)[0]
    assert abs(np.radians(band.deg - 0.12)) < 4 * f.effect_std(band)[0]
    assert f.to_json()["identified"] is True
