"""The world's robot: true mark positions, arrival sides, noise, arm boxes."""

import numpy as np
import pytest

from vision_cal.errors import VisionCalError
from vision_cal.kinematics import ScaraParams, forward
from vision_cal.model import JointBacklash, JointCyclic, RobotModel, SheetAffine
from vision_cal.plan.calibration_plan import PlannedMark, paper_plan
from vision_cal.render.world import (arm_boxes, arm_points, draw_marks, kinematic_joints,
                                     parking_pose)

TRUTH = ScaraParams(344.05, 259.87, -2.57, -8.13, -420.0, -230.0)


def _random_plan(n, rng, *, overshoot=2.0):
    """Marks with random approach sides, each enforced by an overshoot via point."""
    q = rng.uniform([-60, -120], [60, 120], size=(n, 2))
    s = rng.choice([-1, 1], size=(n, 2))
    return [PlannedMark(f"m{i:03d}", tuple(q[i]), "calibration", tuple(int(v) for v in s[i]),
                        (tuple(q[i] - s[i] * overshoot),)) for i in range(n)]


def test_clean_marks_are_the_truth_model_exactly():
    rng = np.random.default_rng(0)
    truth = RobotModel(TRUTH, (JointBacklash(2, 0.3), JointCyclic(1, 2, 0.05, 20.0),
                               SheetAffine(((0.998, 0.0), (0.0, 1.0)))))
    plan = _random_plan(40, rng)
    w = draw_marks(truth, plan, repeatability_mm=0.0, rng=1)
    q = np.array([m.joints_deg for m in plan])
    s = np.array([m.approach for m in plan])
    np.testing.assert_allclose(w.q_deg, q)
    np.testing.assert_array_equal(w.approach, s)
    np.testing.assert_allclose(w.xy_mm, truth.predict(q, s), atol=1e-12)
    assert w.ids == tuple(m.id for m in plan)
    # the effects are really in: the base model alone is off by more than the backlash
    assert np.max(np.linalg.norm(w.xy_mm - forward(TRUTH, q), axis=1)) > 0.3


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


def test_backlash_depends_on_the_real_arrival_side():
    truth = RobotModel(TRUTH, (JointBacklash(1, 0.2),))
    q = (10.0, 30.0)
    from_above = [PlannedMark("a", q, via_deg=((12.0, 32.0),))]
    from_below = [PlannedMark("a", q, via_deg=((8.0, 28.0),))]
    a = draw_marks(truth, from_above, repeatability_mm=0.0).xy_mm[0]
    b = draw_marks(truth, from_below, repeatability_mm=0.0).xy_mm[0]
    # joint 1 lags 0.1 deg either way: 0.2 deg apart at the pen's radius from the base
    r = np.linalg.norm(forward(TRUTH, [q])[0] - TRUTH.base_mm)
    assert np.linalg.norm(a - b) == pytest.approx(np.radians(0.2) * r, rel=1e-6)


def test_repeatability_noise_statistics():
    rng = np.random.default_rng(3)
    truth = RobotModel(TRUTH)
    plan = _random_plan(4000, rng)
    clean = draw_marks(truth, plan, repeatability_mm=0.0).xy_mm
    noisy = draw_marks(truth, plan, repeatability_mm=0.05, rng=7).xy_mm
    e = noisy - clean
    n = len(e)
    assert np.all(np.abs(e.mean(axis=0)) < 4 * 0.05 / np.sqrt(n))
    np.testing.assert_allclose(e.std(axis=0), 0.05, rtol=0.05)   # ~4 sigma of the std
    assert abs(np.corrcoef(e.T)[0, 1]) < 0.06                    # isotropic, independent
    # same rng seed, same world
    np.testing.assert_array_equal(noisy, draw_marks(truth, plan, repeatability_mm=0.05,
                                                    rng=7).xy_mm)


def test_joint_source_is_pluggable():
    truth = RobotModel(TRUTH, (JointBacklash(2, 0.5),))
    plan = paper_plan()
    seen = {}

    def servo(p, home):
        seen["home"] = home
        q = np.array([m.joints_deg for m in p]) + 0.01   # the links stop a little past
        return q, -np.ones((len(p), 2))

    w = draw_marks(truth, plan, home_deg=(1.0, 2.0), repeatability_mm=0.0, joint_source=servo)
    assert seen["home"] == (1.0, 2.0)
    q = np.array([m.joints_deg for m in plan]) + 0.01
    np.testing.assert_allclose(w.xy_mm, truth.predict(q, -np.ones((5, 2))))
    np.testing.assert_array_equal(w.approach, -1)
    with pytest.raises(VisionCalError, match="joint_source"):
        draw_marks(truth, plan, joint_source=lambda p, h: (np.zeros((2, 2)), np.ones((2, 2))))


def test_arm_boxes_run_base_elbow_pen():
    truth = RobotModel(TRUTH, (JointBacklash(2, 0.4),))
    q = (25.0, -70.0)
    (b0, e0, w1, h1), (e1, p1, w2, h2) = arm_boxes(truth, q)
    np.testing.assert_allclose(b0, TRUTH.base_mm)
    assert np.linalg.norm(np.subtract(e0, b0)) == pytest.approx(TRUTH.L1_mm)
    assert np.linalg.norm(np.subtract(p1, e1)) == pytest.approx(TRUTH.L2_mm)
    np.testing.assert_allclose(e0, e1)
    # the pen end is where the true robot puts the pen (approach +1 default)
    np.testing.assert_allclose(p1, truth.predict([q])[0], atol=1e-9)
    assert (w1, h1, w2, h2) == (60.0, 150.0, 40.0, 100.0)
    np.testing.assert_allclose(arm_points(TRUTH, q)[2], forward(TRUTH, [q])[0])


def test_parking_pose_is_over_the_sheet():
    truth = RobotModel(TRUTH)
    extent = (-297.0, -210.0, 297.0, 210.0)
    for seed in range(5):
        q = parking_pose(truth, extent, rng=seed)
        x, y = truth.predict([q])[0]
        assert -257 <= x <= 257 and -170 <= y <= 170


def test_simulated_world_moves_backlash_into_the_controller():
    from vision_cal.model import JointScale
    from vision_cal.render.world import simulated_world

    truth = RobotModel(TRUTH, (JointBacklash(2, 0.2), JointScale(1, 0.002)))
    rng = np.random.default_rng(4)
    plan = _random_plan(6, rng, overshoot=3.0)
    source, model = simulated_world(truth, controller="smc", rng=0)
    assert model.effects == (JointScale(1, 0.002),)
    sim = draw_marks(model, plan, repeatability_mm=0.0, joint_source=source)
    kin = draw_marks(truth, plan, repeatability_mm=0.0)
    # a good controller with gear play lands where the kinematic world with the backlash
    # effect puts the mark: within a few micrometres
    np.testing.assert_array_equal(sim.approach, kin.approach)
    assert np.max(np.linalg.norm(sim.xy_mm - kin.xy_mm, axis=1)) < 0.005
