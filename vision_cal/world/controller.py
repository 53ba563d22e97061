"""Joint tracking controllers: the seed paper's sliding-mode controller and a PD baseline.

Conventions: radians, rad/s, N m at the link side (see :mod:`.dynamics`). The error is
``e = q_ref - q`` where ``q`` is the *motor-encoder* angle (link-side units): the feedback
never sees the gear backlash, as on a real robot.

Sliding-mode control (Slotine & Li; the paper's controller)::

    s = e_dot + lambda e
    u = M_hat(q) (qdd_ref + lambda e_dot) + C_hat(q, qd) qd + F_hat(qd) + K sat(s / phi)

``M_hat``, ``C_hat``, ``F_hat`` come from the controller's own model (a
:class:`ScaraDynamics`, which may differ from the simulated plant); ``K`` bounds the model
error it rejects and ``phi`` is the boundary layer (rad/s) that removes chattering.

PD: ``u = Kp e + Kd e_dot`` (no model, no feed-forward); it lags during motion and settles
slowly against friction, which is why the paper used SMC. Its closed loop has a zero (the
derivative acts on the reference velocity too), so it overshoots a stop slightly even when
over-damped; ``derivative_on_error=False`` (``Kp e - Kd qd``) removes it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from vision_cal.errors import VisionCalError
from vision_cal.world.dynamics import ScaraDynamics


def _sat(x: float) -> float:
    return 1.0 if x > 1.0 else (-1.0 if x < -1.0 else x)


@dataclass(frozen=True)
class SlidingModeController:
    """Sliding-mode tracking controller with a boundary layer."""

    model: ScaraDynamics = field(default_factory=ScaraDynamics)
    lambda_1_s: tuple[float, float] = (40.0, 40.0)
    gain_nm: tuple[float, float] = (20.0, 8.0)
    boundary_rad_s: tuple[float, float] = (0.1, 0.1)

    def __post_init__(self):
        a, b, d = self.model.inertia_constants
        r1, r2 = self.model.reflected_inertia
        m = self.model
        object.__setattr__(self, "_c", (a, b, d, r1, r2, float(m.viscous_nms[0]),
                                        float(m.viscous_nms[1]), float(m.coulomb_nm[0]),
                                        float(m.coulomb_nm[1]), float(m.coulomb_velocity_rad_s)))

    def torque(self, q1, q2, v1, v2, r1, r2, rd1, rd2, rdd1, rdd2):
        """Torques (u1, u2) for encoder state (q, v) and reference (r, rd, rdd), floats."""
        a, b, d, j1, j2, bv1, bv2, fc1, fc2, vs = self._c
        l1, l2 = self.lambda_1_s
        e1, e2 = r1 - q1, r2 - q2
        ed1, ed2 = rd1 - v1, rd2 - v2
        a1 = rdd1 + l1 * ed1
        a2 = rdd2 + l2 * ed2
        c2 = math.cos(q2)
        h = b * math.sin(q2)
        m11 = a + 2.0 * b * c2 + j1
        m12 = d + b * c2
        m22 = d + j2
        # C_hat qd evaluated with the measured velocity
        cq1 = -h * (2.0 * v1 * v2 + v2 * v2)
        cq2 = h * v1 * v1
        f1 = bv1 * rd1 + fc1 * math.tanh(rd1 / vs)
        f2 = bv2 * rd2 + fc2 * math.tanh(rd2 / vs)
        s1 = ed1 + l1 * e1
        s2 = ed2 + l2 * e2
        k1, k2 = self.gain_nm
        p1, p2 = self.boundary_rad_s
        u1 = m11 * a1 + m12 * a2 + cq1 + f1 + k1 * _sat(s1 / p1)
        u2 = m12 * a1 + m22 * a2 + cq2 + f2 + k2 * _sat(s2 / p2)
        return u1, u2


@dataclass(frozen=True)
class PDController:
    """Independent-joint PD on the encoder error (no model)."""

    kp_nm_rad: tuple[float, float] = (2500.0, 600.0)
    kd_nms_rad: tuple[float, float] = (230.0, 45.0)  # over-damped
    derivative_on_error: bool = True

    def torque(self, q1, q2, v1, v2, r1, r2, rd1, rd2, rdd1, rdd2):
        """``Kp e + Kd e_dot``, or ``Kp e - Kd qd`` with ``derivative_on_error=False``
        (no closed-loop zero, hence no overshoot of a stop, but a larger lag)."""
        kp1, kp2 = self.kp_nm_rad
        kd1, kd2 = self.kd_nms_rad
        if not self.derivative_on_error:
            rd1 = rd2 = 0.0
        return (kp1 * (r1 - q1) + kd1 * (rd1 - v1), kp2 * (r2 - q2) + kd2 * (rd2 - v2))


def make_controller(name, *, model: ScaraDynamics | None = None):
    """``"smc"`` or ``"pd"`` (or a controller object, returned as is)."""
    if not isinstance(name, str):
        if not hasattr(name, "torque"):
            raise VisionCalError(f"controller {name!r} has no torque() method", field="controller")
        return name
    if name == "smc":
        return SlidingModeController(model=model or ScaraDynamics())
    if name == "pd":
        return PDController()
    raise VisionCalError(f"unknown controller {name!r}: use 'smc' or 'pd'", field="controller")
