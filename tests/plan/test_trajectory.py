"""Joint trajectories: sampling, knots, limits, approach directions, CSV."""

import numpy as np
import pytest

from vision_cal.dataset.session import resolve_approach
from vision_cal.errors import VisionCalError
from vision_cal.plan.calibration_plan import PlannedMark, informative_plan, paper_plan
from vision_cal.plan.trajectory import (joint_trajectory, plan_trajectory, plan_waypoints,
                                        write_trajectory_csv)
from vision_cal.dataset.session import Sheet, SheetMarker
from vision_cal.model.kinematics import ScaraParams

NOMINAL = ScaraParams(350.0, 260.0, 0.0, 0.0, -400.0, -250.0)


def make_sheet() -> Sheet:
    """An A2 sheet in the SM5's reach with four 40 mm ArUco squares."""
    sq = [np.array([[x, y + 40.0], [x + 40.0, y + 40.0], [x + 40.0, y], [x, y]])
          for x, y in ((-130.0, -500.0), (380.0, -500.0), (-130.0, -160.0), (380.0, -160.0))]
    return Sheet("DICT_5X5_100", tuple(SheetMarker(i, c) for i, c in enumerate(sq)),
                 (594.0, 420.0), (-150.0, -520.0))

VMAX = np.array([90.0, 120.0])
AMAX = np.array([300.0, 400.0])


@pytest.fixture(scope="module")
def plan():
    return informative_plan(NOMINAL, make_sheet(), n_calibration=12, n_validation=4, rng=11,
                            n_candidates=8000)


@pytest.fixture(scope="module")
def traj(plan):
    return plan_trajectory(plan, home_deg=(0.0, 0.0))


def test_samples_every_dt(traj):
    assert traj.t_s[0] == 0.0
    np.testing.assert_allclose(np.diff(traj.t_s), 0.016, rtol=0, atol=1e-12)
    assert traj.q_deg.shape == traj.qd_deg_s.shape == traj.qdd_deg_s2.shape == (len(traj.t_s), 2)


def test_passes_through_waypoints_at_knot_times(plan, traj):
    wp, idx = plan_waypoints(plan, home_deg=(0.0, 0.0))
    assert len(wp) == 1 + 2 * len(plan) and np.sum(idx >= 0) == len(plan)
    np.testing.assert_array_equal(traj.waypoints_deg, wp)
    k = np.rint(traj.knot_t_s / 0.016).astype(int)
    np.testing.assert_allclose(traj.knot_t_s, k * 0.016, atol=1e-12)   # knots on samples
    np.testing.assert_allclose(traj.q_deg[k], wp, atol=1e-9)
    np.testing.assert_allclose(traj.qd_deg_s[k], 0.0, atol=1e-9)      # every waypoint a stop
    assert np.all(np.diff(traj.knot_t_s) > 0)


def test_velocity_and_acceleration_limits(traj):
    assert np.all(np.abs(traj.qd_deg_s) <= VMAX * (1 + 1e-9))
    assert np.all(np.abs(traj.qdd_deg_s2) <= AMAX * (1 + 1e-9))
    # and the limits are used: the longest moves are limit-bound, not padded
    assert np.abs(traj.qd_deg_s).max(axis=0).max() > 0.5 * VMAX.min()


def test_finer_limits_scale_durations():
    wp = np.array([[0.0, 0.0], [90.0, -30.0]])
    fast = joint_trajectory(wp, dwell_s=0.0)
    slow = joint_trajectory(wp, dwell_s=0.0, vmax_deg_s=(45.0, 60.0), amax_deg_s2=(75.0, 100.0))
    # velocity-bound: T = 1.5 * 90 / 90 = 1.5 s; halved speed and quartered accel -> 3 s
    assert fast.duration_s == pytest.approx(1.504, abs=0.016)
    assert slow.duration_s == pytest.approx(3.008, abs=0.016)


def _last_motion_sign(traj, t_knot, j, tol=1e-9):
    k = int(round(t_knot / traj.dt_s))
    q = traj.q_deg[: k + 1, j]
    moved = np.flatnonzero(np.abs(q - q[-1]) > tol)
    return 0 if moved.size == 0 else int(np.sign(q[-1] - q[moved[-1]]))


def test_approach_direction_honoured_without_overshoot(plan, traj):
    mark_knots = traj.knot_t_s[traj.mark_index >= 0]
    for m, tk in zip(plan, mark_knots):
        for j in range(2):
            assert _last_motion_sign(traj, tk, j) == m.approach[j]
        # the final motion (via -> mark) never passes the mark
        k1 = int(round(tk / traj.dt_s))
        k0 = int(round(traj.knot_t_s[list(traj.mark_index).index(plan.index(m)) - 1] / traj.dt_s))
        seg = traj.q_deg[k0:k1 + 1]
        assert np.all((seg - np.array(m.joints_deg)) * np.array(m.approach) <= 1e-9)


def test_paper_plan_matches_the_format_approach_rule():
    """Every mark, every joint, the "did not move" cases included: a joint that has not
    moved since home must be on the format's starting side (+1), one that did not move on
    the last leg on the side of its last motion."""
    from types import SimpleNamespace

    marks = paper_plan()
    traj = plan_trajectory(marks)
    # the rule from the joints alone (no approach given), as a session without approach
    want = resolve_approach([SimpleNamespace(joints_deg=m.joints_deg, approach=None)
                             for m in marks])
    np.testing.assert_array_equal(want, [[1, 1], [1, 1], [-1, 1], [1, 1], [1, -1]])
    knots = traj.knot_t_s[traj.mark_index >= 0]
    unmoved = 0
    for i, tk in enumerate(knots):
        for j in range(2):
            got = _last_motion_sign(traj, tk, j)
            unmoved += got == 0
            assert (got if got != 0 else 1) == want[i, j], (i, j)
    assert unmoved >= 3    # c00 both joints, joint 2 at j1p and j1n: the cases that matter
    assert np.sum(traj.pen_down) == 5


def test_pen_goes_down_after_the_dwell_at_each_mark(plan, traj):
    assert np.sum(traj.pen_down) == len(plan)
    kp = np.flatnonzero(traj.pen_down)
    np.testing.assert_allclose(traj.t_s[kp], traj.pen_t_s)
    np.testing.assert_allclose(traj.q_deg[kp], [m.joints_deg for m in plan], atol=1e-9)
    mark_knots = traj.knot_t_s[traj.mark_index >= 0]
    np.testing.assert_allclose(traj.pen_t_s - mark_knots, 0.304, atol=1e-9)  # 0.3 s -> 19 samples
    assert len(traj.pen_t_s) == len(plan) and np.all(np.diff(traj.pen_t_s) > 0)


def test_zero_motion_mark_takes_no_time():
    marks = [PlannedMark("c00", (0.0, 0.0))]
    traj = plan_trajectory(marks, dwell_s=0.0)
    assert traj.pen_t_s[0] == 0.0 and np.all(traj.q_deg == 0.0)


def test_csv_round_trip(tmp_path, traj):
    path = write_trajectory_csv(tmp_path / "traj.csv", traj)
    lines = path.read_text().splitlines()
    assert lines[0] == "t_s,q1_deg,q2_deg,qd1_deg_s,qd2_deg_s,pen"
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    assert data.shape == (len(traj.t_s), 6)
    np.testing.assert_allclose(data[:, 1:3], traj.q_deg, atol=1e-6)
    np.testing.assert_array_equal(data[:, 5].astype(bool), traj.pen_down)


def test_bad_waypoints_are_refused():
    with pytest.raises(VisionCalError, match="waypoints"):
        joint_trajectory(np.zeros((3, 3)))
    with pytest.raises(VisionCalError, match="finite"):
        joint_trajectory(np.array([[0.0, 0.0], [np.nan, 1.0]]))
