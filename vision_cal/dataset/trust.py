"""Whether a calibration.json may be used: its own ``verdict`` (docs/format.md), read, never
recomputed here.

``design --pilot`` needs a pilot whose verdict is ``ready``, or ``check`` only for what
it could not identify (``verdict.within_valid_for`` ``ready``: the informative plan is
designed to identify it); ``plan`` and ``export`` refuse
one whose verdict is ``not reliable`` unless ``--force``. A calibration.json without a
``verdict`` block (written before it existed) is accepted.
"""

from __future__ import annotations

from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.errors import VisionCalError


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


def _why(reasons: list[str]) -> str:
    return f": {'; '.join(reasons[:3])}" if reasons else ""


def require_ready_pilot(cal: CalibrationResult, path) -> None:
    """Refuse (``VisionCalError``, exit 2) a pilot calibration whose verdict is not ready."""
    status, reasons = verdict_of(cal)
    v = _verdict_block(cal)
    if status == "check" and v is not None and v.get("within_valid_for") == "ready":
        return   # ready inside its valid_for: the informative plan identifies the rest
    if status is not None and status != "ready":
        raise VisionCalError(f"the pilot calibration's verdict is {status!r}, not 'ready'"
                             f"{_why(reasons)}; calibrate the pilot again (more photos, marks "
                             "on free paper) before designing the informative plan",
                             file=str(path), field="verdict.status")


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
