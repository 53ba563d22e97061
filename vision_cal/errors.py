"""The package's one exception type."""

from __future__ import annotations


class VisionCalError(Exception):
    """Any error vision-cal reports to a user: one line naming what to fix.

    ``file`` and ``field`` (when known) are put in front of the message, so
    ``VisionCalError("expected a number", file="session.json", field="marks[2].joints_deg")``
    reads ``session.json: marks[2].joints_deg: expected a number``.
    """

    def __init__(self, message: str, *, file: str | None = None, field: str | None = None):
        self.file = file
        self.field = field
        self.reason = message
        parts = [p for p in (file, field) if p]
        super().__init__(": ".join([*parts, message]))


class CalibrationError(VisionCalError):
    """The data cannot calibrate the model (too few marks, unidentifiable plan)."""
