"""Atomic file writing and JSON reading with one-line errors."""

from __future__ import annotations

import errno
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


def _cannot_write(path: Path, e: OSError, field: str | None = None) -> VisionCalError:
    why = e.strerror or type(e).__name__
    if isinstance(e, FileExistsError) or getattr(e, "errno", None) == errno.ENOTDIR:
        why = "a file is in the way (expected a folder on the path)"
    elif getattr(e, "errno", None) == errno.EROFS:
        why = "read-only file system"
    return VisionCalError(f"cannot write: {why}", file=str(path), field=field)


def output_dir(path, *, field: str | None = None) -> Path:
    """Check (creating nothing) that results can be written into the folder ``path``;
    else one line naming it and the option ``field`` it came from."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise VisionCalError("is a file, expected a folder", file=str(path), field=field)
    probe = path
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    if not probe.is_dir():
        raise VisionCalError(f"cannot write: {probe} is a file, expected a folder",
                             file=str(path), field=field)
    if not os.access(probe, os.W_OK | os.X_OK):
        why = "read-only file system" if _read_only(probe) else "permission denied"
        raise VisionCalError(f"cannot write: {why} ({probe})", file=str(path), field=field)
    return path


def _read_only(path: Path) -> bool:
    try:
        return bool(os.statvfs(path).f_flag & os.ST_RDONLY)
    except OSError:
        return False


def output_file(path, *, field: str | None = None) -> Path:
    """A file path that can be written (its folder created if needed), else one line."""
    path = Path(path)
    if path.is_dir() or str(path).endswith(os.sep):
        raise VisionCalError("is a folder, expected a file name", file=str(path), field=field)
    try:
        output_dir(path.parent, field=field)
    except VisionCalError as e:
        raise VisionCalError(f"cannot write into {path.parent}: {e.reason}", file=str(path),
                             field=field) from e
    return path


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder, then rename.

    Any failure of the file system (a file where a folder should be, a folder where the file
    should be, read-only, full) is one :class:`VisionCalError` naming the path."""
    path = Path(path)
    if path.is_dir():
        raise VisionCalError("cannot write: is a folder, expected a file name", file=str(path))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as e:
        raise _cannot_write(path, e) from e
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(e, OSError):
            raise _cannot_write(path, e) from e
        raise
    return path


def atomic_write_text(path, text: str) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path, obj) -> Path:
    text = json.dumps(_clean(obj), indent=2, default=_default, allow_nan=False)
    return atomic_write_text(path, text + "\n")


def read_text(path, *, what: str = "file") -> str:
    """A UTF-8 text file (a leading byte-order mark, as Windows tools save, is dropped);
    missing or unreadable is one clear line naming it."""
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8-sig")
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
    except RecursionError as e:
        raise VisionCalError("not valid JSON: nested too deeply", file=str(path)) from e
    if not isinstance(obj, dict):
        raise VisionCalError("expected a JSON object at the top level", file=str(path))
    return obj


def read_yaml(path, *, what: str = "file"):
    """Read a YAML document with ``safe_load`` (no tags that build objects or run code);
    a malformed file is one clear line with the line and column."""
    import yaml

    path = Path(path)
    text = read_text(path, what=what)
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise VisionCalError(f"not valid YAML{where}: {problem}", file=str(path)) from e
    except RecursionError as e:
        raise VisionCalError("not valid YAML: nested too deeply", file=str(path)) from e
