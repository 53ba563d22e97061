"""How far beyond its marks a calibration may be used: its own expected error there.

A calibration states an expected target error ``E`` (verdict ``expected_target_error_mm``,
a 95 % radius, from ``n`` held-out marks) for the joints its marks covered; ``E`` itself is
known to a relative ``u = 1 / sqrt(2 n)`` (the relative std of an RMS over ``n`` 2-D
residuals). Beyond the covered range the model is extrapolated, and two things grow:

- **what the fit knows**: the predicted std ``s`` (``plan/uncertainty.predicted_std_mm``,
  the covariance, per axis). Over the covered joint box it is at most ``s_ref``; at a target
  of std ``s`` the expected error becomes ``E_t^2 = E^2 + c^2 (s^2 - s_ref^2)`` (``c =
  sqrt(-2 ln 0.05)``, the 95 % radius per std), within what ``E`` is known to while ``s``
  is at most :func:`std_limit_mm`, ``sqrt(s_ref^2 + E^2 ((1 + u)^2 - 1) / c^2)``;
- **what it could not see**: an error the model lacks that is smooth over the covered span
  ``S`` of a joint (at most quadratic in the angle) and small enough there to pass the
  noise floor grows beyond it like the Chebyshev polynomial ``T_2(1 + 2 d / S)`` at ``d``
  degrees beyond; it keeps ``E`` within ``E (1 + u)`` while ``T_2 <= 1 + u``, so the range
  stretches by :func:`beyond_deg` = ``(sqrt((2 + u) / 2) - 1) S / 2`` (3 % of the span for
  8 held-out marks), never less than ``dataset/valid_for.RANGE_SLACK_DEG``.

A target is inside while both hold (``dataset/valid_for.check``: ``std_mm``,
``std_limit_mm``, ``beyond_deg``): not a hard edge at the last mark. A calibration that
states no ``E`` keeps the slack alone and ``s <= s_ref``.
"""

from __future__ import annotations

import math

import numpy as np

from vision_cal.dataset.covariance import load_covariance
from vision_cal.errors import VisionCalError
from vision_cal.plan.uncertainty import predicted_std_mm

#: 95 % radius of a circular normal 2-D error per unit of its per-axis std
C95 = math.sqrt(-2.0 * math.log(0.05))
#: the covered joint box is sampled on this many angles per joint for ``s_ref``
_GRID = 9


def _stated(doc: dict) -> tuple[float, float] | None:
    """(E, u): the verdict's expected target error and its relative uncertainty (None:
    the calibration states none)."""
    v = doc.get("verdict") if isinstance(doc.get("verdict"), dict) else {}
    e = v.get("expected_target_error_mm")
    if not (isinstance(e, (int, float)) and not isinstance(e, bool) and math.isfinite(e)
            and e > 0):
        return None
    n = (v.get("heldout_floor") or v.get("floor") or {}).get("n_marks")
    if not (isinstance(n, (int, float)) and n >= 1):
        marks = doc.get("marks") if isinstance(doc.get("marks"), dict) else {}
        n = sum(isinstance(m, dict) and m.get("role") == "validation"
                for m in marks.values()) or max(len(marks), 1)
    return float(e), 1.0 / math.sqrt(2.0 * float(n))


def _covered(doc: dict):
    vf = doc.get("valid_for") if isinstance(doc.get("valid_for"), dict) else None
    rng = (vf or {}).get("joints_deg")
    try:
        (lo1, hi1), (lo2, hi2) = ((float(a), float(b)) for a, b in rng)
    except (TypeError, ValueError):
        return None
    return (lo1, hi1), (lo2, hi2)


def beyond_deg(doc: dict) -> tuple[float, float] | None:
    """Per joint, how far beyond the covered range (deg) an error the model could not see
    keeps the stated expected error (module docstring; None: no ``E`` or no range)."""
    stated, box = _stated(doc), _covered(doc)
    if stated is None or box is None:
        return None
    x = math.sqrt((2.0 + stated[1]) / 2.0)
    return tuple(float((x - 1.0) * (hi - lo) / 2.0) for lo, hi in box)


def std_limit_mm(model, doc: dict, *, file: str) -> float | None:
    """The largest predicted std (mm per axis, as plan.csv ``std_mm``) a target may have
    and still be inside what calibration document ``doc`` states (module docstring): from
    the std over its covered joint box (the approach sides it saw) and its verdict's
    expected target error (None: no usable covariance, or no range)."""
    try:
        cov = load_covariance(doc, model, file=file)
    except VisionCalError:   # none usable (plan has read it already): no std to compare
        return None
    box = _covered(doc)
    if cov is None or box is None:
        return None
    g1, g2 = (np.linspace(lo, hi, _GRID) for lo, hi in box)
    q = np.array([[a, b] for a in g1 for b in g2])
    sides = ((doc.get("valid_for") or {}).get("approach_sides") or {})
    s1, s2 = sides.get("1") or [1], sides.get("2") or [1]
    s = np.concatenate([predicted_std_mm(model, cov, q, np.tile([a, b], (len(q), 1)))
                        for a in s1 for b in s2])
    s = s[np.isfinite(s)]
    if not s.size:
        return None
    s_ref = float(s.max())
    stated = _stated(doc)
    if stated is None:
        return s_ref
    e, u = stated
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
