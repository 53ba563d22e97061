"""Sliding-mode and PD controllers on the simulated SCARA; simulate_plan end to end."""

import math

import numpy as np
import pytest

from vision_cal.errors import VisionCalError
from vision_cal.model.kinematics import ScaraParams
from vision_cal.plan.calibration_plan import PlannedMark, informative_plan, paper_plan
from vision_cal.dataset.session import Sheet, SheetMarker, resolve_approach
from vision_cal.world.controller import PDController, SlidingModeController, make_controller
from vision_cal.world.dynamics import ScaraDynamics, Stepper
from vision_cal.world.simulate import simulate_plan

NOMINAL = ScaraParams(350.0, 260.0, 0.0, 0.0, -400.0, -250.0)


def _step_response(ctrl, plant=ScaraDynamics(), target_deg=(2.0, -3.0), q0_deg=(10.0, 40.0),
                   t_end=3.0, dt=1e-3):
    """Encoder error (K, 2) deg of a step from q0 to q0 + target, reference at rest."""
    st = Stepper(plant)
    q1, q2 = math.radians(q0_deg[0]), math.radians(q0_deg[1])
    r1, r2 = q1 + math.radians(target_deg[0]), q2 + math.radians(target_deg[1])
    v1 = v2 = 0.0
    err = []
    for _ in range(int(t_end / dt)):
        u1, u2 = ctrl.torque(q1, q2, v1, v2, r1, r2, 0.0, 0.0, 0.0, 0.0)
        q1, q2, v1, v2 = st.step(q1, q2, v1, v2, u1, u2, dt)
        err.append((r1 - q1, r2 - q2))
    return np.degrees(np.array(err))


def _no_sustained_oscillation(err, dt=1e-3):
    tail = err[-int(0.5 / dt):]                 # last 0.5 s
    before = err[-int(1.0 / dt):-int(0.5 / dt)]
    for j in range(2):
        # decaying: the last half second is no larger than the one before
        assert np.abs(tail[:, j]).max() <= np.abs(before[:, j]).max() + 1e-9
        # no ringing: at most one zero crossing of the error in the last second
        e = err[-int(1.0 / dt):, j]
        assert np.sum(np.diff(np.sign(e[np.abs(e) > 1e-7])) != 0) <= 1


@pytest.mark.parametrize("ctrl, tol_deg", [(SlidingModeController(), 1e-4),
                                           (PDController(), 1e-3)])
def test_step_settles(ctrl, tol_deg):
    err = _step_response(ctrl)
    assert np.abs(err[0]).max() > 1.0          # it really was a step
    assert np.all(np.abs(err[-1]) < tol_deg)
    _no_sustained_oscillation(err)


def test_smc_rejects_model_error():
    """Plant 30% heavier with twice the friction; SMC keeps its nominal model."""
    plant = ScaraDynamics(m1_kg=13.0, m2_kg=6.5, payload_kg=1.3, viscous_nms=(3.0, 1.6),
                          coulomb_nm=(6.0, 3.0))
    err = _step_response(SlidingModeController(), plant=plant)
    assert np.all(np.abs(err[-1]) < 1e-4)
    _no_sustained_oscillation(err)


def _sheet():
    sq = [np.array([[x, y + 40.0], [x + 40.0, y + 40.0], [x + 40.0, y], [x, y]])
          for x, y in ((-130.0, -500.0), (380.0, -500.0), (-130.0, -160.0), (380.0, -160.0))]
    return Sheet("DICT_5X5_100", tuple(SheetMarker(i, c) for i, c in enumerate(sq)),
                 (594.0, 420.0), (-150.0, -520.0))


@pytest.fixture(scope="module")
def plan():
    return informative_plan(NOMINAL, _sheet(), n_calibration=10, n_validation=2, rng=5,
                            n_candidates=8000)


def test_smc_plan_settles_where_planned(plan):
    band = np.array([0.1, 0.06])
    res = simulate_plan(plan, backlash_deg=band, controller="smc")
    s = np.array([m.approach for m in plan])
    q = np.array([m.joints_deg for m in plan])
    assert np.all(np.abs(res.settle_residual_deg) < 1e-4)
    np.testing.assert_allclose(res.motor_deg, q, atol=1e-4)
    np.testing.assert_array_equal(res.approach, s)
    np.testing.assert_allclose(res.link_deg, res.motor_deg - s * band / 2, atol=1e-9)
    # SMC with an exact model tracks the cubic reference to a few thousandths of a degree
    assert np.all(res.tracking_max_deg < 0.02)
    assert np.all(res.tracking_rms_deg <= res.tracking_max_deg)
    assert res.duration_s >= res.reference.duration_s


def test_smc_tracks_better_than_pd(plan):
    smc = simulate_plan(plan[:4], controller="smc")
    pd = simulate_plan(plan[:4], controller="pd")
    assert np.all(pd.tracking_rms_deg > 5 * smc.tracking_rms_deg)
    # PD lags and settles slowly against friction: the pen waits longer
    assert pd.settle_extra_s.sum() > smc.settle_extra_s.sum()
    assert np.all(np.abs(pd.settle_residual_deg) < 1e-4)


def test_paper_plan_arrivals_follow_the_format_rule():
    marks = paper_plan()
    res = simulate_plan(marks, backlash_deg=(0.1, 0.1))
    want = resolve_approach(marks)
    np.testing.assert_array_equal(res.approach, want)
    np.testing.assert_allclose(res.link_deg, res.motor_deg - want * 0.05, atol=2e-3)


def test_encoder_noise_is_reproducible():
    m = [PlannedMark("a", (10.0, 20.0), approach=(1, 1), via_deg=((7.0, 17.0),))]
    a = simulate_plan(m, encoder_noise_deg=1e-3, rng=1, max_settle_s=0.2)
    b = simulate_plan(m, encoder_noise_deg=1e-3, rng=1, max_settle_s=0.2)
    c = simulate_plan(m, encoder_noise_deg=1e-3, rng=2, max_settle_s=0.2)
    np.testing.assert_array_equal(a.motor_deg, b.motor_deg)
    assert not np.array_equal(a.motor_deg, c.motor_deg)


def test_bad_inputs():
    m = [PlannedMark("a", (10.0, 20.0))]
    with pytest.raises(VisionCalError, match="controller"):
        make_controller("lqr")
    with pytest.raises(VisionCalError, match="backlash"):
        simulate_plan(m, backlash_deg=(-0.1, 0.0))
    with pytest.raises(VisionCalError, match="marks"):
        simulate_plan([])


def test_pd_zero_overshoots_a_stop_derivative_on_measurement_does_not(plan):
    band = np.array([0.1, 0.1])
    s = np.array([m.approach for m in plan])
    off = {}
    for on_error in (True, False):
        res = simulate_plan(plan, backlash_deg=band,
                            controller=PDController(derivative_on_error=on_error))
        np.testing.assert_array_equal(res.approach, s)
        off[on_error] = np.abs(res.link_deg - (res.motor_deg - s * band / 2)).max()
    assert off[False] < 1e-9          # every link rests on its lagging flank
    assert off[True] > 0.01           # overshoot then return inside the band
