"""The world's new kinds (joint_terms: coupling and polynomial; drift), anchored on
hand-computed poses: its own code, never the estimator's."""

import math

import numpy as np
import pytest

from vision_cal.errors import VisionCalError
from vision_cal.world.scene import scene_from_dict
from vision_cal.world.truth_model import TrueRobot

P = {"L1_mm": 300.0, "L2_mm": 200.0, "joint_zero_deg": [0.0, 0.0], "base_mm": [0.0, 0.0]}


def test_coupling_turns_joint_2_with_joint_1():
    # joint 2 turns 0.01 deg per degree of joint 1: at q = (30, 0) link 2 is at 0.3 deg
    t = TrueRobot.from_json(P, [{"name": "joint_terms", "joint": 2,
                                  "terms": [{"feature": "q1", "coef": 0.01}]}])
    assert t.link_deg([[30.0, 0.0]])[0] == pytest.approx([30.0, 0.3])
    pen = t.pen_mm([[30.0, 0.0]])[0]
    a, b = math.radians(30.0), math.radians(30.3)
    assert pen == pytest.approx([300 * math.cos(a) + 200 * math.cos(b),
                                 300 * math.sin(a) + 200 * math.sin(b)], abs=1e-9)


def test_polynomial_and_products_and_harmonics():
    t = TrueRobot.from_json(P, [{"name": "joint_terms", "joint": 1, "terms": [
        {"feature": "q1^2", "coef": 1e-4}, {"feature": "q1*q2", "coef": 2e-5},
        {"feature": "sin(3*q2)", "coef": 0.02}, {"feature": "approach1", "coef": -0.01}]}])
    q = np.array([[20.0, 10.0]])
    # 1e-4 * 400 + 2e-5 * 200 + 0.02 * sin(30 deg) - 0.01 * (-1) = 0.04 + 0.004 + 0.01 + 0.01
    assert t.link_deg(q, [[-1, 1]])[0, 0] == pytest.approx(20.064)


def test_drift_linear_and_warmup_from_first_to_last_mark():
    lin = TrueRobot.from_json(P, [{"name": "drift", "param": "z1_deg", "change": 0.1}])
    q = np.zeros((3, 2))
    xy = lin.pen_mm(q, t=[0.0, 0.5, 1.0])
    ang = np.degrees(np.arctan2(xy[:, 1], xy[:, 0]))
    assert ang == pytest.approx([0.0, 0.05, 0.1], abs=1e-9)
    assert lin.pen_mm(q)[:, 1] == pytest.approx(0.0)      # no time: no drift
    warm = TrueRobot.from_json(P, [{"name": "drift", "param": "L1_mm", "change": 0.05,
                                    "shape": "warmup", "tau": 0.25}])
    x = warm.pen_mm(q, t=[0.0, 0.25, 1.0])[:, 0]
    k = (1 - math.exp(-1)) / (1 - math.exp(-4))
    assert x - 500 == pytest.approx([0.0, 0.05 * k, 0.05], abs=1e-9)


def test_scene_reads_the_new_kinds_and_refuses_bad_ones():
    s = scene_from_dict({"robot": {"effects": [
        {"name": "joint_terms", "joint": 2, "terms": [{"feature": "q1*q2", "coef": 1e-5}]},
        {"name": "drift", "param": "base_x_mm", "change": 0.03, "shape": "warmup"}]}})
    tr = s.robot.true_robot
    assert tr.terms[0].feature == "q1*q2" and tr.drift[0].param == "base_x_mm"
    with pytest.raises(VisionCalError, match=r"robot\.effects\[0\]\.param"):
        scene_from_dict({"robot": {"effects": [{"name": "drift", "param": "L3", "change": 1}]}})
    with pytest.raises(VisionCalError, match=r"robot\.effects\[0\]"):
        scene_from_dict({"robot": {"effects": [{"name": "joint_terms", "joint": 2,
                                                "terms": [{"feature": "q3", "coef": 1}]}]}})
