"""SCARA rigid-body dynamics, the fixed-step integrator, and gear backlash.

The world integrates the arm on plain floats (:class:`Stepper`); the vectorised model here
(mass matrix, Coriolis matrix, friction) is the textbook's, written apart from it from the
same constants, and checked against the physics first (symmetric, a point mass's
``m J^T J``, ``M' - 2C`` skew) before the integrator is checked against it."""

import math

import numpy as np
import pytest

from vision_cal.model.kinematics import ScaraParams
from vision_cal.model.robot import JointBacklash, RobotModel
from vision_cal.plan.calibration_plan import PlannedMark
from vision_cal.world.dynamics import ScaraDynamics, Stepper
from vision_cal.world.simulate import simulate_plan

DYN = ScaraDynamics()


def mass_matrix(dyn: ScaraDynamics, q_rad) -> np.ndarray:
    """M(q): (..., 2, 2) for q (..., 2), rotors reflected on the diagonal."""
    q = np.asarray(q_rad, dtype=float)
    a, b, d = dyn.inertia_constants
    r1, r2 = dyn.reflected_inertia
    c2 = np.cos(q[..., 1])
    m = np.empty(q.shape[:-1] + (2, 2))
    m[..., 0, 0] = a + 2 * b * c2 + r1
    m[..., 0, 1] = m[..., 1, 0] = d + b * c2
    m[..., 1, 1] = d + r2
    return m


def coriolis_matrix(dyn: ScaraDynamics, q_rad, qd_rad_s) -> np.ndarray:
    """C(q, qd) (..., 2, 2) with C qd the Coriolis/centrifugal torque."""
    q = np.asarray(q_rad, dtype=float)
    qd = np.asarray(qd_rad_s, dtype=float)
    h = -dyn.inertia_constants[1] * np.sin(q[..., 1])
    c = np.empty(q.shape[:-1] + (2, 2))
    c[..., 0, 0] = h * qd[..., 1]
    c[..., 0, 1] = h * (qd[..., 0] + qd[..., 1])
    c[..., 1, 0] = -h * qd[..., 0]
    c[..., 1, 1] = 0.0
    return c


def forward_dynamics(dyn: ScaraDynamics, q_rad, qd_rad_s, torque_nm) -> np.ndarray:
    """Acceleration (..., 2) under ``torque_nm`` (friction: viscous and smoothed Coulomb)."""
    qd = np.asarray(qd_rad_s, dtype=float)
    friction = (np.asarray(dyn.viscous_nms) * qd
                + np.asarray(dyn.coulomb_nm) * np.tanh(qd / dyn.coulomb_velocity_rad_s))
    rhs = (np.asarray(torque_nm, dtype=float)
           - np.einsum("...ij,...j->...i", coriolis_matrix(dyn, q_rad, qd), qd) - friction)
    return np.linalg.solve(mass_matrix(dyn, q_rad), rhs[..., None])[..., 0]


def kinetic_energy(dyn: ScaraDynamics, q_rad, qd_rad_s) -> float:
    qd = np.asarray(qd_rad_s, dtype=float)
    return float(0.5 * qd @ mass_matrix(dyn, q_rad) @ qd)


def test_mass_matrix_symmetric_positive_definite():
    q = np.column_stack([np.zeros(50), np.linspace(-np.pi, np.pi, 50)])
    m = mass_matrix(DYN, q)
    np.testing.assert_allclose(m, np.swapaxes(m, -1, -2))
    assert np.all(np.linalg.eigvalsh(m) > 0.1)
    # stretched arm has the largest joint-1 inertia, folded arm the smallest
    assert m[25, 0, 0] > m[0, 0, 0]


def test_mass_matrix_matches_textbook_point_values():
    """A massless arm carrying a point mass at the tip: M = m J^T J (+ rotors)."""
    d = ScaraDynamics(m1_kg=0.0, m2_kg=0.0, payload_kg=2.0, rotor_inertia_kgm2=(0.0, 0.0))
    q = np.array([0.3, 1.1])
    L1, L2 = d.L1_m, d.L2_m
    J = np.array([[-L1 * np.sin(q[0]) - L2 * np.sin(q.sum()), -L2 * np.sin(q.sum())],
                  [L1 * np.cos(q[0]) + L2 * np.cos(q.sum()), L2 * np.cos(q.sum())]])
    np.testing.assert_allclose(mass_matrix(d, q), 2.0 * J.T @ J, atol=1e-12)


def test_mdot_minus_2c_is_skew_symmetric():
    rng = np.random.default_rng(0)
    for _ in range(5):
        q, qd = rng.normal(size=2), rng.normal(size=2)
        h = 1e-6
        mdot = (mass_matrix(DYN, q + h * qd) - mass_matrix(DYN, q - h * qd)) / (2 * h)
        n = mdot - 2 * coriolis_matrix(DYN, q, qd)
        np.testing.assert_allclose(n, -n.T, atol=1e-7)


def test_stepper_follows_forward_dynamics():
    st = Stepper(DYN)
    q, qd, u = np.array([0.2, -0.7]), np.array([0.5, -0.3]), np.array([3.0, -1.0])
    dt = 1e-6
    _, _, v1, v2 = st.step(q[0], q[1], qd[0], qd[1], u[0], u[1], dt)
    acc = (np.array([v1, v2]) - qd) / dt
    np.testing.assert_allclose(acc, forward_dynamics(DYN, q, qd, u), rtol=1e-4)


def test_free_motion_conserves_energy_without_friction():
    d = ScaraDynamics(viscous_nms=(0.0, 0.0), coulomb_nm=(0.0, 0.0))
    st = Stepper(d)
    s = (0.0, 0.5, 2.0, -3.0)
    e0 = kinetic_energy(d, s[:2], s[2:])
    for _ in range(2000):  # 2 s at 1 kHz
        s = st.step(*s, 0.0, 0.0, 1e-3)
    e1 = kinetic_energy(d, s[:2], s[2:])
    assert abs(e1 - e0) < 0.01 * e0


def test_friction_stops_a_coasting_arm():
    st = Stepper(DYN)
    s = (0.0, 0.5, 1.0, -1.0)
    for _ in range(3000):
        s = st.step(*s, 0.0, 0.0, 1e-3)
    assert abs(s[2]) < 1e-3 and abs(s[3]) < 1e-3   # no instability from the stiff tanh


def test_play_in_the_simulated_run():
    """The gear play simulate_plan really uses (not a helper production never calls):
    dragged in + the link lags band/2 behind the encoder; a reversal smaller than the band
    leaves the link where it was (and on the same side); a larger one drags it back."""
    band = (0.25, 0.0)
    up = PlannedMark("a", (10.0, 0.0), approach=(1, 1))
    small_back = PlannedMark("b", (9.9, 0.0), approach=(-1, 1))     # 0.1 < 0.25 deg
    big_back = PlannedMark("c", (9.5, 0.0), approach=(-1, 1))       # 0.4 > 0.25 deg
    res = simulate_plan([up, small_back, big_back], backlash_deg=band)
    # hand-computed: link = 10 - 0.125 = 9.875 at a; the encoder moves to 9.9, still inside
    # the band (9.9 - 0.125 < 9.875 < 9.9 + 0.125): the link stays at 9.875; at c the
    # encoder is at 9.5, dragging the link from above: 9.5 + 0.125 = 9.625
    np.testing.assert_allclose(res.link_deg[:, 0], [9.875, 9.875, 9.625], atol=2e-4)
    np.testing.assert_array_equal(res.approach[:, 0], [1, 1, -1])


def _one_mark(q, approach, over=3.0):
    q = np.asarray(q, dtype=float)
    s = np.asarray(approach)
    return PlannedMark("m", tuple(q), approach=tuple(int(x) for x in s),
                       via_deg=(tuple(q - s * over),))


@pytest.mark.parametrize("band", [(0.2, 0.1), (0.05, 0.3)])
def test_backlash_offset_depends_on_approach(band):
    q = (25.0, -70.0)
    plus = simulate_plan([_one_mark(q, (1, 1))], backlash_deg=band)
    minus = simulate_plan([_one_mark(q, (-1, -1))], backlash_deg=band)
    # each lags against its approach, so the two differ by the full band
    np.testing.assert_allclose(minus.link_deg[0] - plus.link_deg[0], band, atol=2e-4)
    np.testing.assert_allclose(plus.link_deg[0], plus.motor_deg[0] - np.array(band) / 2,
                               atol=1e-9)
    np.testing.assert_allclose(minus.link_deg[0], minus.motor_deg[0] + np.array(band) / 2,
                               atol=1e-9)
    np.testing.assert_array_equal(plus.approach[0], [1, 1])
    np.testing.assert_array_equal(minus.approach[0], [-1, -1])
    # and JointBacklash (the fitted model) predicts the same joint angles
    model = RobotModel(ScaraParams(344.0, 260.0),
                       (JointBacklash(1, band[0]), JointBacklash(2, band[1])))
    for res, s in ((plus, (1, 1)), (minus, (-1, -1))):
        want = np.degrees(model.joint_angles_rad([q], [s]))[0]
        np.testing.assert_allclose(res.link_deg[0], want, atol=2e-4)


def test_mixed_approach_and_zero_backlash():
    q = (-40.0, 90.0)
    res = simulate_plan([_one_mark(q, (1, -1))], backlash_deg=(0.1, 0.1))
    np.testing.assert_allclose(res.link_deg[0] - res.motor_deg[0], [-0.05, 0.05], atol=1e-9)
    none = simulate_plan([_one_mark(q, (-1, 1))])
    np.testing.assert_array_equal(none.link_deg, none.motor_deg)
    np.testing.assert_allclose(none.link_deg[0], q, atol=2e-4)
    np.testing.assert_array_equal(none.approach[0], [-1, 1])


def test_link_stays_put_when_its_joint_does_not_move():
    """The paper's j1p after c00: joint 2 does not move, its link keeps the home side."""
    marks = [PlannedMark("a", (0.0, 10.0), approach=(1, -1), via_deg=((-3.0, 13.0),)),
             PlannedMark("b", (20.0, 10.0), approach=(1, -1))]
    res = simulate_plan(marks, backlash_deg=(0.1, 0.2))
    assert res.link_deg[0, 1] - res.motor_deg[0, 1] == pytest.approx(0.1, abs=1e-9)
    # joint 2's encoder is only nudged by joint 1's motion (coupling, < 1e-3 deg): the link
    # stays on the side it was left on, not where a fresh + approach would put it
    assert res.link_deg[1, 1] == pytest.approx(res.link_deg[0, 1], abs=1e-3)
    assert res.link_deg[1, 1] - 10.0 > 0.09
    assert res.approach[1, 1] == -1
    assert math.isclose(res.link_deg[1, 0] - res.motor_deg[1, 0], -0.05, abs_tol=1e-9)
