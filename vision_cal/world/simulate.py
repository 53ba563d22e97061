"""Simulate a plan: trajectory -> controller -> dynamics -> backlash -> where the pen lands.

Conventions: angles in degrees at the API, in the *commanded* joint frame (before the
model's zero offsets ``z1, z2``): ``link_deg`` is what :func:`vision_cal.model.kinematics.forward`
(or :class:`vision_cal.model.robot.RobotModel` without its joint effects) turns into a pen
position. Inside, radians at a fixed step ``dt_s`` (semi-implicit Euler, see
:class:`~vision_cal.world.dynamics.Stepper`), plain floats in one lean loop.

At each mark's pen-down time (end of the dwell, from :mod:`vision_cal.plan.trajectory`)
the arm must be settled: both encoder errors below ``settle_tol_deg`` and both speeds
below ``settle_tol_deg`` per 16 ms. If not, the reference is held and the pen waits, up to
``max_settle_s`` (then it goes down anyway; ``settle_extra_s`` and
``settle_residual_deg`` report it). The rest of the trajectory is shifted by the wait.
The pen lands where the *links* settled, not where the joints were commanded.

Gear backlash is a play operator between encoder and link (see :mod:`.dynamics`); the
link starts at ``home - band/2`` (as if the arm had last moved in +, the format's default
approach). ``approach`` is the side of the band in contact at pen-down (the sign of the
last motion that dragged the link); with no backlash it is the sign of the last encoder
motion larger than ``settle_tol_deg``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vision_cal.errors import VisionCalError
from vision_cal.model.motion import TRAJECTORY_DT_S
from vision_cal.plan.trajectory import Trajectory, plan_trajectory
from vision_cal.world.controller import make_controller
from vision_cal.world.dynamics import ScaraDynamics, Stepper


@dataclass(frozen=True, eq=False)
class SimResult:
    """What the simulated robot did (N marks, degrees).

    motor_deg (N, 2): encoder angles at pen-down; link_deg (N, 2): link angles at pen-down
    (what the pen position depends on); approach (N, 2) +-1: the side each joint arrived
    from; settle_residual_deg (N, 2):
    encoder minus command at pen-down; settle_extra_s (N,): extra wait for settling;
    tracking_rms_deg / tracking_max_deg (2,): encoder minus reference over the whole run;
    reference: the commanded trajectory (at its own sampling period); duration_s and n_steps:
    the simulated run's length.
    """

    motor_deg: np.ndarray
    link_deg: np.ndarray
    approach: np.ndarray
    settle_residual_deg: np.ndarray
    settle_extra_s: np.ndarray
    tracking_rms_deg: np.ndarray
    tracking_max_deg: np.ndarray
    reference: Trajectory
    duration_s: float
    n_steps: int


def simulate_plan(marks, *, home_deg=(0.0, 0.0), backlash_deg=(0.0, 0.0), controller="smc",
                  dynamics: ScaraDynamics | None = None, dt_s: float = 0.001,
                  settle_tol_deg: float = 1e-4, rng=None, encoder_noise_deg: float = 0.0,
                  max_settle_s: float = 5.0,
                  trajectory: Trajectory | None = None, trajectory_dt_s: float = TRAJECTORY_DT_S,
                  **trajectory_kwargs) -> SimResult:
    """Run ``marks`` (list of :class:`~vision_cal.plan.calibration_plan.PlannedMark`).

    ``controller``: ``"smc"`` (its model is the default :class:`ScaraDynamics`, so a
    different ``dynamics`` plant is a model error it must reject), ``"pd"`` or an object
    with ``torque(...)``. ``encoder_noise_deg``: standard deviation of white noise on the
    fed-back encoder angles (uses ``rng``). ``trajectory_kwargs`` go to
    :func:`~vision_cal.plan.trajectory.joint_trajectory`, sampled every ``trajectory_dt_s``
    (``trajectory`` may be given directly instead); the controller follows the spline itself
    at every simulation step.
    """
    rng = np.random.default_rng(rng)
    band = _checked_inputs(marks, dt_s, backlash_deg)
    n_marks = len(marks)
    traj = trajectory if trajectory is not None else plan_trajectory(
        marks, home_deg=home_deg, dt_s=trajectory_dt_s, **trajectory_kwargs)
    plant = Stepper(dynamics or ScaraDynamics())
    ctrl = make_controller(controller)
    n_ref, (r1s, r2s, rd1s, rd2s, rdd1s, rdd2s), pen_at = _reference(traj, dt_s, n_marks)
    marks_rad = np.radians(np.array([m.joints_deg for m in marks], dtype=float).reshape(-1, 2))

    tol = math.radians(settle_tol_deg)
    vtol = tol / TRAJECTORY_DT_S  # settled: slower than the tolerance per trajectory period
    hb1, hb2 = math.radians(band[0]) / 2, math.radians(band[1]) / 2
    # direction tracker: width of the band, or the settle tolerance with no backlash
    dh1 = hb1 if hb1 > 0 else tol / 2
    dh2 = hb2 if hb2 > 0 else tol / 2
    q1, q2 = r1s[0], r2s[0]
    v1 = v2 = 0.0
    l1, l2 = q1 - hb1, q2 - hb2           # last moved in + (format default)
    g1, g2 = q1 - dh1, q2 - dh2           # direction trackers
    sg1 = sg2 = 1.0
    max_hold = int(round(max_settle_s / dt_s))

    motor = np.zeros((n_marks, 2))
    link = np.zeros((n_marks, 2))
    arrival = np.zeros((n_marks, 2))
    resid = np.zeros((n_marks, 2))
    extra = np.zeros(n_marks)
    err_sq1 = err_sq2 = 0.0
    err_max1 = err_max2 = 0.0
    n_err = 0
    steps = 0
    advance = _advancer(ctrl.torque, plant.step, dt_s, math.radians(encoder_noise_deg), rng)
    track = _tracker(hb1, hb2, dh1, dh2)

    for k in range(n_ref):
        if k:  # control from the state and reference at step k - 1, over one step
            j = k - 1
            q1, q2, v1, v2 = advance(q1, q2, v1, v2, r1s[j], r2s[j], rd1s[j], rd2s[j],
                                     rdd1s[j], rdd2s[j])
            steps += 1
        a1, a2 = r1s[k], r2s[k]
        # backlash (play operator) and direction trackers
        l1, l2, g1, g2, sg1, sg2 = track(q1, q2, l1, l2, g1, g2, sg1, sg2)
        e1, e2 = abs(a1 - q1), abs(a2 - q2)
        err_sq1 += e1 * e1
        err_sq2 += e2 * e2
        err_max1 = e1 if e1 > err_max1 else err_max1
        err_max2 = e2 if e2 > err_max2 else err_max2
        n_err += 1
        i = pen_at.get(k)
        if i is None:
            continue
        m1, m2 = marks_rad[i]
        hold = 0
        while hold < max_hold and not (abs(q1 - m1) < tol and abs(q2 - m2) < tol
                                       and abs(v1) < vtol and abs(v2) < vtol):
            q1, q2, v1, v2 = advance(q1, q2, v1, v2, m1, m2, 0.0, 0.0, 0.0, 0.0)
            steps += 1
            hold += 1
            l1, l2, g1, g2, sg1, sg2 = track(q1, q2, l1, l2, g1, g2, sg1, sg2)
        motor[i] = (q1, q2)
        link[i] = (l1, l2)
        arrival[i] = (sg1, sg2)
        resid[i] = (q1 - m1, q2 - m2)
        extra[i] = hold * dt_s

    return _result(motor, link, arrival, resid, extra, (err_sq1, err_sq2),
                   (err_max1, err_max2), n_err, traj, steps, dt_s)


def _advancer(torque, step, dt_s: float, sigma: float, rng):
    """One simulation step, ``advance(q1, q2, v1, v2, a1, a2, b1, b2, c1, c2) -> (q1, q2,
    v1, v2)``: the controller's torque for the reference ``a`` (angle), ``b`` (speed), ``c``
    (acceleration) from the encoder (with white noise of std ``sigma`` rad when positive),
    then the plant over ``dt_s``. A closure over plain floats: the loop's cost is its calls."""
    noise = sigma > 0

    def advance(q1, q2, v1, v2, a1, a2, b1, b2, c1, c2):
        if noise:
            n1, n2 = rng.normal(0.0, sigma, 2)
            u1, u2 = torque(q1 + n1, q2 + n2, v1, v2, a1, a2, b1, b2, c1, c2)
        else:
            u1, u2 = torque(q1, q2, v1, v2, a1, a2, b1, b2, c1, c2)
        return step(q1, q2, v1, v2, u1, u2, dt_s)

    return advance


def _tracker(hb1: float, hb2: float, dh1: float, dh2: float):
    """``track(q1, q2, l1, l2, g1, g2, sg1, sg2) -> (l1, l2, g1, g2, sg1, sg2)``: the play
    operator (link inside the band ``+-hb`` about the motor) and the direction trackers
    (half width ``dh``) giving the side each joint last moved towards (its arrival sign)."""

    def track(q1, q2, l1, l2, g1, g2, sg1, sg2):
        """Play operator (link inside the band about the motor) and, with a tiny band,
        the side each joint last moved towards (its arrival sign)."""
        if l1 < q1 - hb1:
            l1 = q1 - hb1
        elif l1 > q1 + hb1:
            l1 = q1 + hb1
        if l2 < q2 - hb2:
            l2 = q2 - hb2
        elif l2 > q2 + hb2:
            l2 = q2 + hb2
        if g1 < q1 - dh1:
            g1, sg1 = q1 - dh1, 1.0
        elif g1 > q1 + dh1:
            g1, sg1 = q1 + dh1, -1.0
        if g2 < q2 - dh2:
            g2, sg2 = q2 - dh2, 1.0
        elif g2 > q2 + dh2:
            g2, sg2 = q2 + dh2, -1.0
        return l1, l2, g1, g2, sg1, sg2

    return track


def _checked_inputs(marks, dt_s: float, backlash_deg) -> np.ndarray:
    """The backlash band per joint (deg); refuses a non-positive step, a negative or
    non-finite band, and a plan without marks."""
    if not dt_s > 0:
        raise VisionCalError(f"dt_s must be positive, got {dt_s}", field="dt_s")
    band = np.broadcast_to(np.asarray(backlash_deg, dtype=float), (2,))
    if np.any(band < 0) or not np.all(np.isfinite(band)):
        raise VisionCalError(f"backlash_deg must be >= 0, got {backlash_deg!r}",
                             field="backlash_deg")
    if len(marks) == 0:
        raise VisionCalError("the plan has no marks", field="marks")
    return band


def _reference(traj: Trajectory, dt_s: float, n_marks: int):
    """The reference at the simulation step (the analytic spline, radians):
    ``(n_ref, (r1, r2, rd1, rd2, rdd1, rdd2) as lists of floats, {step: mark index})``;
    refuses a trajectory whose pen-downs are not one per mark."""
    n_ref = int(round(traj.duration_s / dt_s)) + 1
    t_ref = np.arange(n_ref) * dt_s
    r, rd, rdd = (np.radians(x) for x in traj.evaluate(t_ref))
    columns = (r[:, 0].tolist(), r[:, 1].tolist(), rd[:, 0].tolist(), rd[:, 1].tolist(),
               rdd[:, 0].tolist(), rdd[:, 1].tolist())
    pen_k = np.rint(traj.pen_t_s / dt_s).astype(int)
    if len(pen_k) != n_marks:
        raise VisionCalError(f"trajectory has {len(pen_k)} pen-downs for {n_marks} marks")
    return n_ref, columns, {int(k): i for i, k in enumerate(pen_k)}


def _result(motor, link, arrival, resid, extra, err_sq, err_max, n_err: int,
            traj: Trajectory, steps: int, dt_s: float) -> SimResult:
    """The run in degrees: per-mark states (radians in), the tracking error's RMS from its
    sums of squares and its maximum."""
    return SimResult(
        motor_deg=np.degrees(motor), link_deg=np.degrees(link), approach=arrival,
        settle_residual_deg=np.degrees(resid), settle_extra_s=extra,
        tracking_rms_deg=np.degrees(np.sqrt(np.array(err_sq) / max(n_err, 1))),
        tracking_max_deg=np.degrees(np.array(err_max)),
        reference=traj, duration_s=steps * dt_s, n_steps=steps)
