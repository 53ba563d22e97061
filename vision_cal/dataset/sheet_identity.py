"""Which printed sheet a calibration was made on (issue 19): calibration.json records the
sheet's ``sheet_id`` (``sheet.printed.sheet_id``, when ``vision-cal sheet`` made it) and its
geometry (dictionary, marker count, marker extent, and a fingerprint of the markers'
corners), so ``design --pilot`` refuses a calibration of another sheet instead of placing
marks with a model measured in another frame."""

from __future__ import annotations

import hashlib
import json

import numpy as np

from vision_cal.errors import VisionCalError


def _fingerprint(dictionary, markers) -> str:
    key = json.dumps([dictionary, sorted([int(m["id"]), np.round(np.asarray(
        m["corners_mm"], float), 3).tolist()] for m in markers)])
    return hashlib.sha256(key.encode()).hexdigest()[:16]


def sheet_identity(sheet_raw) -> dict | None:
    """calibration.json's ``sheet`` block for a session's (already checked) sheet block, or
    None without markers."""
    if not isinstance(sheet_raw, dict) or not sheet_raw.get("markers"):
        return None
    markers = sheet_raw["markers"]
    c = np.concatenate([np.asarray(m["corners_mm"], float).reshape(-1, 2) for m in markers])
    printed = sheet_raw.get("printed") or {}
    return {"sheet_id": printed.get("sheet_id"),
            "aruco_dictionary": sheet_raw.get("aruco_dictionary"),
            "n_markers": len(markers),
            "markers_extent_mm": np.round(np.concatenate([c.min(axis=0), c.max(axis=0)]),
                                          3).tolist(),
            "fingerprint": _fingerprint(sheet_raw.get("aruco_dictionary"), markers)}


def check_same_sheet(cal_doc: dict, sheet_raw, *, file: str, sheet_file: str) -> None:
    """Refuse (one line naming the calibration) a calibration recorded on another sheet
    than ``sheet_raw``; a calibration without the record (older versions) is not checked."""
    rec = cal_doc.get("sheet")
    now = sheet_identity(sheet_raw)
    if not isinstance(rec, dict) or now is None or rec.get("fingerprint") is None:
        return
    if rec.get("fingerprint") == now["fingerprint"]:
        return
    ids = (f"sheet_id {rec.get('sheet_id')}, not {now['sheet_id']}"
           if rec.get("sheet_id") and now["sheet_id"] else
           f"{rec.get('n_markers')} markers over {rec.get('markers_extent_mm')} mm, not "
           f"{now['n_markers']} over {now['markers_extent_mm']} mm")
    raise VisionCalError(f"was calibrated on another sheet than {sheet_file} ({ids}): "
                         "calibrate the pilot photographed on this sheet, or give its "
                         "sheet.json", file=file, field="sheet")
