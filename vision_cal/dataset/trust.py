"""Whether a calibration.json may be used: its own ``verdict`` (docs/format.md), read, never
recomputed here.

``design --pilot`` takes a pilot whose verdict is ``ready`` or ``check`` (the informative
plan needs the pilot's model to millimetres: its marks keep a safety margin of 5 mm and
more) and refuses one ``not reliable``, which would make the design wrong; the verdict's
``reason_codes`` say which of a ``check`` pilot's reasons the informative plan exists to
fix (:data:`FIXED_BY_THE_PLAN`). ``plan`` and ``export`` refuse one whose verdict is ``not
reliable`` unless ``--force``. A calibration.json without a ``verdict`` block (written
before it existed) is accepted.
"""

from __future__ import annotations

from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.errors import VisionCalError

#: a pilot's shortfalls the informative plan exists to fix (verdict ``reason_codes``):
#: effects a pilot cannot identify (its valid_for), the print from one camera place
FIXED_BY_THE_PLAN = {"not_identified": "effects a pilot cannot identify",
                     "print_one_place": "the print from one camera place"}


def _verdict_block(doc) -> dict | None:
    """The ``verdict`` block of a calibration (its :class:`CalibrationResult`, or the
    document as :func:`~vision_cal.dataset.calibration.load_calibration` returns it)."""
    v = (doc.verdict if isinstance(doc, CalibrationResult)
         else doc.get("verdict") if isinstance(doc, dict) else None)
    return v if isinstance(v, dict) else None


def verdict_of(doc) -> tuple[str | None, list[str]]:
    """(status or None, reasons) of a calibration (see :func:`_verdict_block`)."""
    v = _verdict_block(doc)
    if v is None:
        return None, []
    reasons = v.get("reasons") or []
    return v.get("status"), [str(r) for r in reasons] if isinstance(reasons, list) else []


def _per_reason(v: dict | None, key: str, n: int, default: str) -> list[str]:
    """The verdict's ``reason_codes`` or ``reason_levels``, one per reason (``default``
    where a block written before them, or a shorter list, says none)."""
    got = (v or {}).get(key)
    got = [str(c) for c in got] if isinstance(got, list) else []
    return (got + [default] * n)[:n]


def _why(reasons: list[str]) -> str:
    return f": {'; '.join(reasons[:3])}" if reasons else ""


def require_usable_pilot(cal: CalibrationResult, path) -> tuple[str, ...]:
    """Refuse (``VisionCalError``, exit 2) a pilot calibration whose verdict is ``not
    reliable`` (its reasons, worst first, quoted); a ``check`` pilot is taken, and the
    lines to print say which of its shortfalls the informative plan is designed to fix and
    which other reasons are left to look at (by kind: ``verdict.reason_codes``)."""
    status, reasons = verdict_of(cal)
    if status == "not reliable":
        raise VisionCalError(f"the pilot calibration's verdict is 'not reliable'"
                             f"{_why(reasons)}: a plan placed with its model would be "
                             "wrong; calibrate the pilot again (more photos, marks on free "
                             "paper) before designing the informative plan",
                             file=str(path), field="verdict.status")
    if status != "check":
        return ()
    v = _verdict_block(cal)
    levels = _per_reason(v, "reason_levels", len(reasons), "check")
    codes = [c for c, lvl in zip(_per_reason(v, "reason_codes", len(reasons), "other"), levels)
             if lvl != "ready"]   # a pilot's by-design notes are no shortfall
    fixed = [w for c, w in FIXED_BY_THE_PLAN.items() if c in codes]
    left = sorted({c for c in codes if c not in FIXED_BY_THE_PLAN})
    lines = [f"the pilot's verdict is 'check' ({path}): usable to design the informative "
             "plan"]
    if fixed:
        lines.append(f"  the informative plan is designed to fix: {', '.join(fixed)}")
    if left:
        n = sum(c not in FIXED_BY_THE_PLAN for c in codes)
        lines.append(f"  {n} other reason(s) to look at before drawing ({', '.join(left)}): "
                     f"{path} verdict.reasons")
    return tuple(lines)


def refuse_unreliable(doc: dict, path, *, force: bool) -> str | None:
    """Refuse a calibration whose verdict is "not reliable" unless ``force``; with it, the
    warning line to print (None when there is nothing to say)."""
    status, reasons = verdict_of(doc)
    if status != "not reliable":
        return None
    msg = f"the calibration's verdict is 'not reliable'{_why(reasons)}"
    if not force:
        raise VisionCalError(f"{msg}; give --force to use it anyway", file=str(path),
                             field="verdict.status")
    return f"vision-cal: warning: {path}: {msg} (used because of --force)"
