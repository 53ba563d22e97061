"""The world's robot: true mark positions, arrival sides, noise, arm boxes.

The anchors below are worked out by hand from the contract's formulas
(docs/format.md, docs/conventions.md), not from any code: an arm with
L1 = 300, L2 = 200, base (-100, 50), zeros (10, -20) commanded to q = (80, -70) has
phi1 = 90 deg and phi1 + phi2 = 0 deg, so the elbow is at (-100, 350) and the pen at
(100, 350), i.e. pen - base = (200, 300). A rotation of joint 1 by d turns (200, 300) by d
about the base: (200 cos d - 300 sin d, 200 sin d + 300 cos d).
"""

import numpy as np
import pytest

from vision_cal.errors import VisionCalError
from vision_cal.model.kinematics import ScaraParams
from vision_cal.model.robot import JointBacklash, JointCyclic, JointScale, RobotModel, SheetAffine
from vision_cal.plan.calibration_plan import PlannedMark, paper_plan
from vision_cal.world.truth_model import TrueRobot
from vision_cal.world.drawing import (arm_boxes, arm_points, draw_marks, kinematic_joints,
                                     parking_pose)

TRUTH = ScaraParams(344.05, 259.87, -2.57, -8.13, -420.0, -230.0)
ANCHOR = {"L1_mm": 300.0, "L2_mm": 200.0, "joint_zero_deg": [10.0, -20.0],
          "base_mm": [-100.0, 50.0]}
Q = (80.0, -70.0)


def _true(params: ScaraParams, *effects) -> TrueRobot:
    """The world's robot from the JSON blocks (the only thing it shares with the model)."""
    return TrueRobot.from_json(params.to_json(), [e.to_json() for e in effects])


def _anchor(*effects: dict) -> TrueRobot:
    return TrueRobot.from_json(ANCHOR, list(effects))


def _random_plan(n, rng, *, overshoot=2.0):
    """Marks with random approach sides, each enforced by an overshoot via point."""
    q = rng.uniform([-60, -120], [60, 120], size=(n, 2))
    s = rng.choice([-1, 1], size=(n, 2))
    return [PlannedMark(f"m{i:03d}", tuple(q[i]), "calibration", tuple(int(v) for v in s[i]),
                        (tuple(q[i] - s[i] * overshoot),)) for i in range(n)]


# ------------------------------------------------------------------ hand-computed anchors


def test_anchor_base_model():
    np.testing.assert_allclose(_anchor().pen_mm([Q]), [[100.0, 350.0]], atol=1e-9)
    np.testing.assert_allclose(_anchor().arm_points([Q])[0],
                               [[-100.0, 50.0], [-100.0, 350.0], [100.0, 350.0]], atol=1e-9)


def test_anchor_backlash_lags_against_the_approach():
    # band 0.2 deg on joint 1: arriving turning counter-clockwise (+1) the link stops
    # 0.1 deg short, i.e. clockwise: d = -0.1 deg -> pen (100.52329, 349.65048);
    # arriving from -1 it stops 0.1 deg counter-clockwise -> (99.47610, 350.34861)
    w = _anchor({"name": "joint_backlash", "joint": 1, "deg": 0.2})
    np.testing.assert_allclose(w.pen_mm([Q], [[1, 1]]), [[100.52329, 349.65048]], atol=2e-5)
    np.testing.assert_allclose(w.pen_mm([Q], [[-1, 1]]), [[99.47610, 350.34861]], atol=2e-5)
    # joint 2 approach does not move joint 1's play
    np.testing.assert_allclose(w.pen_mm([Q], [[1, -1]]), [[100.52329, 349.65048]], atol=2e-5)


def test_anchor_gear_scale():
    # joint 2 turns 1.01 times the command: -70 -> -70.7, phi1 + phi2 = -0.7 deg:
    # pen = elbow (-100, 350) + 200 (cos 0.7, -sin 0.7) = (99.98507, 347.55660)
    w = _anchor({"name": "joint_scale", "joint": 2, "scale": 0.01})
    np.testing.assert_allclose(w.pen_mm([Q]), [[99.98507, 347.55660]], atol=2e-5)


def test_anchor_cyclic_error():
    # 0.05 deg * sin(2 * q1 + 30 deg) on joint 1 with z1 = 60, q1 = 30 (phi1 = 90 again):
    # sin(60 + 30) = 1, so joint 1 turns +0.05 deg: pen (99.73812, 350.17442)
    params = dict(ANCHOR, joint_zero_deg=[60.0, -20.0])
    w = TrueRobot.from_json(params, [{"name": "joint_cyclic", "joint": 1, "harmonic": 2,
                                      "deg": 0.05, "phase_deg": 30.0}])
    np.testing.assert_allclose(w.pen_mm([(30.0, -70.0)]), [[99.73812, 350.17442]], atol=2e-5)


def test_anchor_sheet_shrink():
    # the paper shrank along x: matrix [[1.002, 0], [0, 1]] about the sheet origin; the
    # pen at (100, 350) in the arm frame reads (100.2, 350) on the printed sheet
    m = {"name": "sheet_affine", "matrix": [[1.002, 0.0], [0.0, 1.0]]}
    w = _anchor(m)
    np.testing.assert_allclose(w.pen_mm([Q]), [[100.2, 350.0]], atol=1e-9)
    # physically shrunk: the point printed at x = 100 lies at 100 / 1.002 = 99.80040 mm
    # in the arm frame, which is where the camera sees it
    T = w.T_render(np.eye(4))
    np.testing.assert_allclose(T @ [100.0, 40.0, 0.0, 1.0], [99.80040, 40.0, 0.0, 1.0],
                               atol=1e-5)


def test_world_and_estimator_agree_on_every_effect():
    """Two independent codes of the same formulas (the world's and the estimator's)."""
    rng = np.random.default_rng(0)
    effects = (JointBacklash(2, 0.3), JointCyclic(1, 2, 0.05, 20.0), JointScale(2, -0.003),
               JointCyclic(2, 1, 0.02, -70.0), SheetAffine(((0.998, 0.001), (0.001, 1.0))))
    q = rng.uniform(-150, 150, (50, 2))
    s = rng.choice([-1, 1], (50, 2))
    np.testing.assert_allclose(_true(TRUTH, *effects).pen_mm(q, s),
                               RobotModel(TRUTH, effects).predict(q, s), atol=1e-9)


# ------------------------------------------------------------------ drawing a plan


def test_clean_marks_follow_the_plan():
    rng = np.random.default_rng(0)
    truth = _true(TRUTH, JointBacklash(2, 0.3), JointCyclic(1, 2, 0.05, 20.0),
                  SheetAffine(((0.998, 0.0), (0.0, 1.0))))
    plan = _random_plan(40, rng)
    w = draw_marks(truth, plan, repeatability_mm=0.0, rng=1)
    q = np.array([m.joints_deg for m in plan])
    s = np.array([m.approach for m in plan])
    np.testing.assert_allclose(w.q_deg, q)
    np.testing.assert_array_equal(w.approach, s)
    np.testing.assert_allclose(w.xy_mm, truth.pen_mm(q, s), atol=1e-12)
    assert w.ids == tuple(m.id for m in plan)
    # the estimator's model without the effects is off by more than the backlash
    base = RobotModel(TRUTH).predict(q)
    assert np.max(np.linalg.norm(w.xy_mm - base, axis=1)) > 0.3
    with pytest.raises(VisionCalError, match="TrueRobot"):
        draw_marks(RobotModel(TRUTH), plan)


def test_approach_follows_the_motion_without_vias():
    plan = paper_plan()
    q, s = kinematic_joints(plan, (0.0, 0.0))
    # c00 (0,0): nothing moved: +1 +1; j1p: +1; j1n: -1; j2p: joint 1 moves back up (+1)...
    np.testing.assert_array_equal(s, [[1, 1], [1, 1], [-1, 1], [1, 1], [1, -1]])
    np.testing.assert_array_equal(s, [m.approach for m in plan])


def test_via_points_decide_the_arrival_side():
    # the move goes up, but the via overshoots so the last motion is downwards
    plan = [PlannedMark("a", (10.0, 10.0), approach=(-1, -1), via_deg=((12.0, 11.0),)),
            PlannedMark("b", (5.0, 20.0), approach=(1, -1), via_deg=((4.0, 20.5),))]
    q, s = kinematic_joints(plan, (0.0, 0.0))
    np.testing.assert_array_equal(s, [[-1, -1], [1, -1]])
    # a joint that does not move on the last leg keeps its sign from the leg before
    plan = [PlannedMark("a", (10.0, 10.0), via_deg=((12.0, 10.0),))]
    _, s = kinematic_joints(plan, (0.0, 0.0))
    np.testing.assert_array_equal(s, [[-1, 1]])


def test_backlash_direction_through_the_plan():
    # the anchor arm, joint 1 band 0.2 deg: reached from above (via 82) it last turned
    # clockwise (-1) and stops 0.1 deg counter-clockwise of the command; from below (via 78)
    # it stops 0.1 deg clockwise. Hand-computed pens as in the backlash anchor.
    truth = _anchor({"name": "joint_backlash", "joint": 1, "deg": 0.2})
    from_above = [PlannedMark("a", Q, via_deg=((82.0, -68.0),))]
    from_below = [PlannedMark("a", Q, via_deg=((78.0, -72.0),))]
    a = draw_marks(truth, from_above, repeatability_mm=0.0).xy_mm[0]
    b = draw_marks(truth, from_below, repeatability_mm=0.0).xy_mm[0]
    np.testing.assert_allclose(a, [99.47610, 350.34861], atol=2e-5)
    np.testing.assert_allclose(b, [100.52329, 349.65048], atol=2e-5)


def test_repeatability_noise_statistics():
    rng = np.random.default_rng(3)
    truth = _true(TRUTH)
    plan = _random_plan(4000, rng)
    clean = draw_marks(truth, plan, repeatability_mm=0.0).xy_mm
    noisy = draw_marks(truth, plan, repeatability_mm=0.05, rng=7).xy_mm
    e = noisy - clean
    n = len(e)
    assert np.all(np.abs(e.mean(axis=0)) < 4 * 0.05 / np.sqrt(n))
    # std of a sample std ~ sigma / sqrt(2n): 4 of them is 4.5 % at n = 4000
    np.testing.assert_allclose(e.std(axis=0), 0.05, rtol=4 / np.sqrt(2 * n))
    assert abs(np.corrcoef(e.T)[0, 1]) < 4 / np.sqrt(n)          # isotropic, independent
    # same rng seed, same world
    np.testing.assert_array_equal(noisy, draw_marks(truth, plan, repeatability_mm=0.05,
                                                    rng=7).xy_mm)


def test_joint_source_is_pluggable():
    truth = _true(TRUTH, JointBacklash(2, 0.5))
    plan = paper_plan()
    seen = {}

    def servo(p, home):
        seen["home"] = home
        q = np.array([m.joints_deg for m in p]) + 0.01   # the links stop a little past
        return q, -np.ones((len(p), 2))

    w = draw_marks(truth, plan, home_deg=(1.0, 2.0), repeatability_mm=0.0, joint_source=servo)
    assert seen["home"] == (1.0, 2.0)
    q = np.array([m.joints_deg for m in plan]) + 0.01
    np.testing.assert_allclose(w.xy_mm, truth.pen_mm(q, -np.ones((5, 2))))
    np.testing.assert_array_equal(w.approach, -1)
    with pytest.raises(VisionCalError, match="joint_source"):
        draw_marks(truth, plan, joint_source=lambda p, h: (np.zeros((2, 2)), np.ones((2, 2))))


def test_arm_boxes_run_base_elbow_pen():
    truth = _anchor({"name": "joint_backlash", "joint": 1, "deg": 0.2})
    (b0, e0, w1, h1), (e1, p1, w2, h2) = arm_boxes(truth, Q)
    np.testing.assert_allclose(b0, [-100.0, 50.0])
    # joint 1 lags 0.1 deg (approach +1 by default): elbow at 300 (cos 89.9, sin 89.9)
    np.testing.assert_allclose(e0, [-100.0 + 0.52360, 50.0 + 299.99954], atol=2e-5)
    np.testing.assert_allclose(e0, e1)
    np.testing.assert_allclose(p1, [100.52329, 349.65048], atol=2e-5)
    assert (w1, h1, w2, h2) == (60.0, 150.0, 40.0, 100.0)
    np.testing.assert_allclose(arm_points(truth, Q)[2], p1)


def test_parking_pose_is_over_the_sheet():
    truth = _true(TRUTH)
    extent = (-297.0, -210.0, 297.0, 210.0)
    for seed in range(5):
        q = parking_pose(truth, extent, rng=seed)
        x, y = truth.pen_mm([q])[0]
        assert -257 <= x <= 257 and -170 <= y <= 170


def test_simulated_world_moves_backlash_into_the_controller():
    from vision_cal.world.drawing import simulated_world

    truth = _true(TRUTH, JointBacklash(2, 0.2), JointScale(1, 0.002))
    rng = np.random.default_rng(4)
    plan = _random_plan(6, rng, overshoot=3.0)
    source, model = simulated_world(truth, controller="smc", rng=0)
    assert model.backlash_deg == (0.0, 0.0) and model.scale == (0.002, 0.0)
    sim = draw_marks(model, plan, repeatability_mm=0.0, joint_source=source)
    kin = draw_marks(truth, plan, repeatability_mm=0.0)
    # a good controller with gear play lands where the kinematic world with the backlash
    # effect puts the mark: within a few micrometres
    np.testing.assert_array_equal(sim.approach, kin.approach)
    assert np.max(np.linalg.norm(sim.xy_mm - kin.xy_mm, axis=1)) < 0.005
