"""Atomic file writing and JSON reading with one-line errors."""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np

from vision_cal.errors import VisionCalError


def _default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")


def _clean(o):
    """Replace non-finite floats by None so the file stays strict JSON."""
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, np.ndarray):
        return _clean(o.tolist())
    if isinstance(o, np.generic):
        return _clean(o.item())
    return o


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder, then rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return path


def atomic_write_text(path, text: str) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path, obj) -> Path:
    text = json.dumps(_clean(obj), indent=2, default=_default, allow_nan=False)
    return atomic_write_text(path, text + "\n")


def read_text(path, *, what: str = "file") -> str:
    """A UTF-8 text file; missing or unreadable is one clear line naming it."""
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError as e:
        raise VisionCalError(f"{what} not found", file=str(path)) from e
    except (OSError, UnicodeDecodeError) as e:
        raise VisionCalError(f"cannot read: {e}", file=str(path)) from e


def read_json(path) -> dict:
    """Read a JSON object; a missing or malformed file is one clear line."""
    path = Path(path)
    text = read_text(path)
    try:
        obj = json.loads(text, parse_constant=lambda c: float(c))
    except json.JSONDecodeError as e:
        raise VisionCalError(f"not valid JSON (line {e.lineno}, column {e.colno}: {e.msg})",
                             file=str(path)) from e
    if not isinstance(obj, dict):
        raise VisionCalError("expected a JSON object at the top level", file=str(path))
    return obj
