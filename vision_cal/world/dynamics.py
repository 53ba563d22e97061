"""Rigid-body dynamics of a 2-link SCARA moving in the horizontal plane, with gear backlash.

Conventions:

- Joint angles ``q = [q1, q2]`` in radians inside this module (link-side units: a motor
  angle is given divided by its gear ratio, so motor and link angles compare directly),
  velocities rad/s, torques N m at the link side. ``q2`` is relative to link 1.
- The plane is horizontal: no gravity acts on q1, q2.
- Links are uniform bars (mass ``m``, length ``L``, centre of mass at ``L/2``) and a
  point payload sits at the tip. Each motor's rotor inertia ``J`` is reflected through its
  gear ratio ``N`` as ``J N^2`` on the diagonal of the mass matrix.
- Friction per joint: viscous ``b qd`` plus Coulomb ``Fc tanh(qd / v_s)`` (smoothed so the
  integration stays stable; :func:`step` treats it linearly-implicitly, so any ``v_s``
  integrates at 1 kHz).

Backlash (dead band of ``backlash_deg`` per joint) is modelled kinematically on the link
side, as a play operator between the motor-side angle ``m`` and the link angle ``l``::

    l <- clip(l, m - band/2, m + band/2)

The link is dragged only when the band is closed; inside the band it keeps its angle (the
link-side friction holds it). The link's inertia is carried with the motor in the mass
matrix (the band is a fraction of a degree, so M(q) is the same on both sides), so the
play operator changes no dynamics and integrates stably at any step. After a motion in
direction ``s`` the link rests at ``m - s * band / 2``: it lags against its approach, the
convention of :class:`vision_cal.model.robot.JointBacklash` (``-s * band / 2``). This is the
friction-dominated limit: a real link may coast into the other flank when it decelerates
faster than its own friction would stop it, which is why calibration plans end each move
with a short, slow overshoot move.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class ScaraDynamics:
    """Physical constants of a horizontal 2-link SCARA (SM5-like defaults, SI units)."""

    L1_m: float = 0.344
    L2_m: float = 0.260
    m1_kg: float = 10.0
    m2_kg: float = 5.0
    payload_kg: float = 1.0
    rotor_inertia_kgm2: tuple[float, float] = (2.0e-4, 1.0e-4)
    gear_ratio: tuple[float, float] = (80.0, 50.0)
    viscous_nms: tuple[float, float] = (1.5, 0.8)
    coulomb_nm: tuple[float, float] = (3.0, 1.5)
    coulomb_velocity_rad_s: float = 0.01

    # -- the three inertia constants of the planar 2-link arm -------------------------
    @property
    def inertia_constants(self) -> tuple[float, float, float]:
        """(a, b, d) with M = [[a + 2b cos q2, d + b cos q2], [d + b cos q2, d]] (+ rotors)."""
        L1, L2, m1, m2, mp = self.L1_m, self.L2_m, self.m1_kg, self.m2_kg, self.payload_kg
        I1 = m1 * L1**2 / 12
        I2 = m2 * L2**2 / 12
        lc1, lc2 = L1 / 2, L2 / 2
        d = I2 + m2 * lc2**2 + mp * L2**2
        a = I1 + m1 * lc1**2 + m2 * L1**2 + mp * L1**2 + d
        b = m2 * L1 * lc2 + mp * L1 * L2
        return a, b, d

    @property
    def reflected_inertia(self) -> tuple[float, float]:
        """Rotor inertia seen at each joint, J N^2 (kg m^2)."""
        return (self.rotor_inertia_kgm2[0] * self.gear_ratio[0] ** 2,
                self.rotor_inertia_kgm2[1] * self.gear_ratio[1] ** 2)


class Stepper:
    """Fixed-step integrator of :class:`ScaraDynamics` on plain floats (fast inner loop).

    One :meth:`step` is a semi-implicit Euler step: the velocity update treats friction
    linearly-implicitly, ``(M + dt dF/dqd) dqd = dt (u - C qd - F(qd))``, then
    ``q += dt * qd_new``. Stable at 1 kHz for the default constants with any Coulomb
    smoothing scale.
    """

    __slots__ = ("a", "b", "d", "r1", "r2", "bv1", "bv2", "fc1", "fc2", "vs")

    def __init__(self, dyn: ScaraDynamics):
        self.a, self.b, self.d = dyn.inertia_constants
        self.r1, self.r2 = dyn.reflected_inertia
        self.bv1, self.bv2 = (float(x) for x in dyn.viscous_nms)
        self.fc1, self.fc2 = (float(x) for x in dyn.coulomb_nm)
        self.vs = float(dyn.coulomb_velocity_rad_s)

    def step(self, q1, q2, v1, v2, u1, u2, dt):
        """Advance (q1, q2, v1, v2) by ``dt`` under torques (u1, u2); returns the new state."""
        c2 = math.cos(q2)
        s2 = math.sin(q2)
        b = self.b
        m11 = self.a + 2.0 * b * c2 + self.r1
        m12 = self.d + b * c2
        m22 = self.d + self.r2
        h = b * s2
        cq1 = -h * (2.0 * v1 * v2 + v2 * v2)
        cq2 = h * v1 * v1
        t1 = math.tanh(v1 / self.vs)
        t2 = math.tanh(v2 / self.vs)
        f1 = self.bv1 * v1 + self.fc1 * t1
        f2 = self.bv2 * v2 + self.fc2 * t2
        k1 = self.bv1 + self.fc1 * (1.0 - t1 * t1) / self.vs
        k2 = self.bv2 + self.fc2 * (1.0 - t2 * t2) / self.vs
        a11 = m11 + dt * k1
        a22 = m22 + dt * k2
        r1 = dt * (u1 - cq1 - f1)
        r2 = dt * (u2 - cq2 - f2)
        det = a11 * a22 - m12 * m12
        dv1 = (a22 * r1 - m12 * r2) / det
        dv2 = (a11 * r2 - m12 * r1) / det
        v1 += dv1
        v2 += dv2
        return q1 + dt * v1, q2 + dt * v2, v1, v2

