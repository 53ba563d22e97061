"""Content-addressed cache of per-photo detections.

Key = SHA-256 of (measuring-code version, the session parts that change a detection:
sheet, pen diameter, declared camera) and the photo's bytes. Entries are pickles written
through a temporary file and a rename, so an interrupted run never leaves a torn entry;
an unreadable entry is treated as absent.
"""

from __future__ import annotations

import hashlib
import json
import pickle
from pathlib import Path

import numpy as np

from vision_cal.dataset.io import atomic_write_bytes

#: bump when anything that changes a detection changes
CODE_VERSION = "measure-3"


def session_fingerprint(session) -> str:
    cam = session.camera
    parts = {"sheet": session.sheet.to_json() if session.sheet else None,
             "pen": session.pen_mark_diameter_mm,
             "camera": None if cam is None else {"size": list(cam.size_px),
                                                 "K": np.asarray(cam.K).tolist(),
                                                 "dist": np.asarray(cam.dist).tolist()}}
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def cache_key(data: bytes, fingerprint: str) -> str:
    h = hashlib.sha256()
    h.update(CODE_VERSION.encode())
    h.update(fingerprint.encode())
    h.update(hashlib.sha256(data).digest())
    return h.hexdigest()


class DetectionCache:
    def __init__(self, folder):
        self.folder = Path(folder)

    def _path(self, key: str) -> Path:
        return self.folder / key[:2] / f"{key}.pkl"

    def get(self, key: str):
        p = self._path(key)
        try:
            return pickle.loads(p.read_bytes())
        except (OSError, pickle.UnpicklingError, EOFError, AttributeError, ValueError):
            return None

    def put(self, key: str, value) -> None:
        atomic_write_bytes(self._path(key), pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL))
