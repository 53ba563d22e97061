"""Datasets: session.json, truth.json, calibration.json and the plan CSVs (vision-cal/1)."""

from vision_cal.dataset.io import atomic_write_json, atomic_write_text, read_json
from vision_cal.dataset.session import (
    Camera, ImageEntry, Mark, NominalRobot, Session, Sheet, SheetMarker, load_session,
    resolve_approach,
)

__all__ = ["Camera", "ImageEntry", "Mark", "NominalRobot", "Session", "Sheet", "SheetMarker",
           "atomic_write_json", "atomic_write_text", "load_session", "read_json",
           "resolve_approach"]
