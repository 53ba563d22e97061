"""The world's own tool and joint 4 (world/truth_model.py): hand-computed anchors."""

import numpy as np
import pytest

from vision_cal.errors import VisionCalError
from vision_cal.world.truth_model import TrueRobot

PARAMS = {"L1_mm": 300.0, "L2_mm": 200.0, "joint_zero_deg": [0.0, 0.0], "base_mm": [0.0, 0.0]}


def test_world_tool_anchors():
    w = TrueRobot.from_json({**PARAMS, "tool_mm": [30.0, 0.0]})
    np.testing.assert_allclose(w.pen_mm([[0, 0, 0], [0, 0, 90], [90, 0, 0], [0, 90, -90]]),
                               [[530, 0], [500, 30], [0, 530], [330, 200]], atol=1e-9)
    np.testing.assert_allclose(w.pen_mm([[0, 0]]), [[530, 0]], atol=1e-9)  # q4 = 0


def test_world_joint4_effects():
    w = TrueRobot.from_json({**PARAMS, "tool_mm": [0.0, 40.0]}, [
        {"name": "joint_backlash", "joint": 4, "deg": 0.2},
        {"name": "joint_scale", "joint": 4, "scale": 0.01}])
    a = np.radians(90 * 1.01 + 0.1 + 90)   # approached from below: lags by -(-1) * 0.1
    np.testing.assert_allclose(w.pen_mm([[0, 0, 90]], [[1, 1, -1]])[0],
                               [500 + 40 * np.cos(a), 40 * np.sin(a)], atol=1e-9)
    with pytest.raises(VisionCalError):
        TrueRobot.from_json(PARAMS, [{"name": "joint_cyclic", "joint": 4, "harmonic": 1,
                                      "deg": 0.1}])


def test_world_draws_with_joint4_and_tracks_its_side():
    from vision_cal.plan.calibration_plan import PlannedMark
    from vision_cal.world.drawing import draw_marks, joint4_sides

    np.testing.assert_array_equal(joint4_sides([30, 30, -10, 50]), [1, 1, -1, 1])
    w = TrueRobot.from_json({**PARAMS, "tool_mm": [0.0, 40.0]},
                            [{"name": "joint_backlash", "joint": 4, "deg": 0.2}])
    plan = [PlannedMark("a", (0.0, 0.0)), PlannedMark("b", (0.0, 0.0))]
    m = draw_marks(w, plan, repeatability_mm=0.0, joint4_deg=[90.0, 0.0])
    a = np.radians([90 - 0.1 + 90, 0 + 0.1 + 90])   # +1 then -1: lags against its motion
    np.testing.assert_allclose(m.xy_mm, np.column_stack([500 + 40 * np.cos(a), 40 * np.sin(a)]),
                               atol=1e-9)
