"""How far beyond its marks a calibration may be used: its own expected error there.

A target beyond the joint range the marks covered is extrapolated: the model's predicted
std there (``plan/uncertainty.predicted_std_mm``, from the fit's covariance, per axis)
grows with the distance from the marks. The calibration states an expected target error
``E`` (verdict ``expected_target_error_mm``, a 95 % radius, from ``n`` held-out marks) over
the places it measured, where the predicted std is at most ``s_ref`` (the largest at its
own marks). At a target of std ``s`` the expected error grows to

    E_t^2 = E^2 + c^2 (s^2 - s_ref^2)          c = sqrt(-2 ln 0.05): 95 % radius per std

and the stated figure still holds while ``E_t`` is within what ``E`` itself is known to,
``E (1 + 1 / sqrt(2 n))`` (the relative std of an RMS over ``n`` 2-D residuals): so a target
is inside while ``s <= std_limit_mm``, with

    std_limit^2 = s_ref^2 + E^2 ((1 + 1 / sqrt(2 n))^2 - 1) / c^2

(``s_ref`` alone when the calibration states no ``E``). ``dataset/valid_for.check`` takes
it (``std_mm=``, ``std_limit_mm=``): not a hard edge at the last mark.
"""

from __future__ import annotations

import math

import numpy as np

from vision_cal.dataset.covariance import load_covariance
from vision_cal.errors import VisionCalError
from vision_cal.plan.uncertainty import predicted_std_mm

#: 95 % radius of a circular normal 2-D error per unit of its per-axis std
C95 = math.sqrt(-2.0 * math.log(0.05))


def std_limit_mm(model, doc: dict, *, file: str) -> float | None:
    """The largest predicted std (mm per axis, as plan.csv ``std_mm``) a target may have
    and still be inside what calibration document ``doc`` states (module docstring): from
    the std at its marks (ok ones) or poses, with their commands and approach sides, and
    its verdict's expected target error (None: no covariance, or no marks)."""
    try:
        cov = load_covariance(doc, model, file=file)
    except VisionCalError:   # none usable (plan has read it already): no std to compare
        return None
    marks = doc.get("marks") if isinstance(doc.get("marks"), dict) else {}
    poses = doc.get("poses") if isinstance(doc.get("poses"), list) else []
    seen = [m for m in list(marks.values()) + poses if isinstance(m, dict)
            and m.get("status", "ok") == "ok" and isinstance(m.get("joints_deg"), list)
            and len(m["joints_deg"]) >= 2]
    if cov is None or not seen:
        return None
    q = [m["joints_deg"][:2] for m in seen]
    a = [(list(m.get("approach") or []) + [1, 1])[:2] for m in seen]
    s = predicted_std_mm(model, cov, q, a)
    s = s[np.isfinite(s)]
    if not s.size:
        return None
    s_ref = float(s.max())
    v = doc.get("verdict") if isinstance(doc.get("verdict"), dict) else {}
    e = v.get("expected_target_error_mm")
    if not (isinstance(e, (int, float)) and math.isfinite(e) and e > 0):
        return s_ref
    n = ((v.get("heldout_floor") or v.get("floor") or {}).get("n_marks")
         or len([m for m in seen if m.get("role") == "validation"]) or len(seen))
    u = 1.0 / math.sqrt(2.0 * max(int(n), 1))
    return math.sqrt(s_ref**2 + e**2 * ((1.0 + u) ** 2 - 1.0) / C95**2)


def std_at_mm(model, doc: dict, q_deg, approach, *, file: str) -> list | None:
    """The predicted std (mm per axis) of commands ``q_deg`` (N, 2) with ``approach``
    (N, 2) under calibration document ``doc`` (None: no usable covariance)."""
    try:
        cov = load_covariance(doc, model, file=file)
    except VisionCalError:
        return None
    if cov is None or not len(q_deg):
        return None
    return [float(v) for v in predicted_std_mm(model, cov, q_deg, approach)]
