"""The seed paper's method (Jeong, Son, Lee, Choi): circles, then L1, L2, a, b.

Marks at a common joint-2 angle and three or more joint-1 angles lie on a circle about
the base; marks at a common joint-1 angle and three or more joint-2 angles lie on a
circle about the elbow. Then (the paper's eqs 10-13 with explicit atan2 signs; the
printed eqs 12-13 swap x and y)::

    L1 = |c_elbow - c_base|            L2 = r_elbow
    z1 = atan2(c_elbow - c_base) - q1_e          (q1_e: the elbow group's joint-1 angle)
    z2 = atan2(pen - c_elbow) - z1 - q1_e - q2   (at the elbow group's mark nearest q2 = 0,
                                                  the zero-return mark, as the paper does)

The paper's a and b are |z1| and |z2|. Marks without both circles give a
:class:`vision_cal.model.lsq.FailedFit` (falsy, with the reason), not an exception:
the least-squares run adds the circles only where the plan has them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision_cal.estimate.circles import Circle
from vision_cal.model.lsq import FailedFit
from vision_cal.model.kinematics import ScaraParams


@dataclass(frozen=True)
class PaperResult:
    params: ScaraParams
    circle_base: Circle
    circle_elbow: Circle

    def or_raise(self) -> "PaperResult":
        """This result (the twin of :meth:`FailedFit.or_raise`)."""
        return self


def _groups(values: np.ndarray, others: np.ndarray, tol: float = 1e-6) -> list[np.ndarray]:
    """Indices grouped by equal ``values`` with at least 3 distinct ``others``."""
    out = []
    for v in np.unique(np.round(values / tol) * tol):
        idx = np.flatnonzero(np.abs(values - v) <= tol)
        if len(np.unique(np.round(others[idx], 6))) >= 3:
            out.append(idx)
    return sorted(out, key=lambda g: (-len(g), -np.ptp(others[g])))


def paper_method(q_deg, xy_mm) -> PaperResult | FailedFit:
    """Calibrate the base model from marks (N, 2) at commanded joints (N, 2) deg; a
    :class:`FailedFit` naming the missing circle when the marks do not have it."""
    q = np.asarray(q_deg, dtype=float).reshape(-1, 2)
    p = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
    gb = _groups(q[:, 1], q[:, 0])
    ge = _groups(q[:, 0], q[:, 1])
    if not gb:
        return FailedFit("the paper's method needs 3 marks at one joint-2 angle and three "
                         "joint-1 angles (the base circle): none found")
    if not ge:
        return FailedFit("the paper's method needs 3 marks at one joint-1 angle and three "
                         "joint-2 angles (the elbow circle): none found")
    b, e = gb[0], ge[0]
    cb = Circle.from_estimate(p[b])
    ce = Circle.from_estimate(p[e])
    if not cb or not ce:
        return cb if not cb else ce
    d = np.subtract(ce.center_mm, cb.center_mm)
    L1 = float(np.hypot(*d))
    q1e = float(q[e[0], 0])
    z1 = np.arctan2(d[1], d[0]) - np.radians(q1e)
    k = e[np.argmin(np.abs(q[e, 1]))]
    ang = np.arctan2(p[k, 1] - ce.center_mm[1], p[k, 0] - ce.center_mm[0])
    z2 = ang - z1 - np.radians(q1e) - np.radians(q[k, 1])
    z2 = (z2 + np.pi) % (2 * np.pi) - np.pi
    z1 = (z1 + np.pi) % (2 * np.pi) - np.pi
    params = ScaraParams(L1, ce.radius_mm, float(np.degrees(z1)), float(np.degrees(z2)),
                         cb.center_mm[0], cb.center_mm[1])
    return PaperResult(params, cb, ce)


def pilot_params(q_deg, xy_mm) -> ScaraParams:
    """The base model from a pilot run's marks (the renderer's ``pilot`` calibrator);
    :class:`vision_cal.errors.CalibrationError` when the marks have no circles."""
    return paper_method(q_deg, xy_mm).or_raise().params
