"""Typed reading of JSON/YAML fields with one-line errors (docs/format.md's every file).

:class:`FieldReader` is the one owner of "a field from a file, checked, or one line naming
the file and the field": session.json, sheet.json, calibration.json, the robot file and
the scene files all read through it (scene files add bounds in ``world/scene._R``).
"""

from __future__ import annotations

import math
import reprlib

from vision_cal.errors import VisionCalError

#: sanity bounds of a valid file: no sheet, robot or pen mark is 100 m across, and no SCARA
#: joint is commanded beyond two turns either way
MAX_MM = 1e5
MAX_JOINT_DEG = 720.0
MAX_PEN_MM = 50.0
MAX_IMAGE_PX = 100_000
MAX_K_PX = 1e7
MAX_DIST = 1e3


_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxlist, _REPR.maxdict, _REPR.maxstring, _REPR.maxlong = 3, 4, 4, 60, 40


def _short(v, n: int = 60) -> str:
    """``repr`` of a value from a file, cut to fit in one line of an error."""
    try:
        t = _REPR.repr(v)  # bounded: a huge value (a YAML alias bomb) is never printed whole
    except (RecursionError, ValueError):  # deeply nested, or an int too long to print
        t = f"<{type(v).__name__}>"
    return t if len(t) <= n else t[:n - 3] + "..."


class FieldReader:
    """Typed field access that names the file and the field in every error (session.json,
    calibration.json and the robot file use the same one)."""

    def __init__(self, file: str):
        self.file = file

    def fail(self, where: str, msg: str):
        raise VisionCalError(msg, file=self.file, field=where)

    def get(self, obj: dict, key: str, where: str, *, required=True):
        if not isinstance(obj, dict):
            self.fail(where, f"expected an object, got {type(obj).__name__}")
        if key not in obj:
            if required:
                self.fail(f"{where}.{key}" if where else key, "missing required field")
            return None
        return obj[key]

    def number(self, v, where: str, *, lo: float | None = None, hi: float | None = None,
               positive: bool = False, what: str = "number") -> float:
        """A finite JSON number, optionally within [lo, hi] (and > 0 with ``positive``)."""
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(where, f"expected a number, got {type(v).__name__} {_short(v)}")
        try:
            x = float(v)
        except OverflowError:
            x = math.inf
        if not math.isfinite(x):
            self.fail(where, f"expected a finite number, got {_short(v)}")
        if positive and x <= 0:
            self.fail(where, f"expected a positive {what}, got {_short(v)}")
        if (lo is not None and x < lo) or (hi is not None and x > hi):
            self.fail(where, f"expected a {what} between {lo:g} and {hi:g}, got {_short(v)}")
        return x

    def vector(self, v, where: str, n: int, **limits) -> tuple[float, ...]:
        if not isinstance(v, list) or len(v) != n:
            self.fail(where, f"expected a list of {n} numbers, got {_short(v)}")
        return tuple(self.number(x, f"{where}[{i}]", **limits) for i, x in enumerate(v))

    def length(self, v, where: str, *, positive: bool = False) -> float:
        """A length in mm: a position or size on a sheet, a link, a pen mark."""
        return self.number(v, where, lo=-MAX_MM, hi=MAX_MM, positive=positive,
                           what="length in mm")

    def point(self, v, where: str) -> tuple[float, float]:
        return self.vector(v, where, 2, lo=-MAX_MM, hi=MAX_MM, what="length in mm")

    def angles(self, v, where: str) -> tuple[float, float]:
        return self.vector(v, where, 2, lo=-MAX_JOINT_DEG, hi=MAX_JOINT_DEG,
                           what="joint angle in degrees")

    def string(self, v, where: str) -> str:
        if not isinstance(v, str) or not v:
            self.fail(where, f"expected a non-empty string, got {_short(v)}")
        return v

    def list_(self, v, where: str, *, nonempty=False) -> list:
        if not isinstance(v, list):
            self.fail(where, f"expected a list, got {type(v).__name__}")
        if nonempty and not v:
            self.fail(where, "expected a non-empty list")
        return v

    def section(self, obj, where: str, allowed: tuple[str, ...]) -> dict:
        """An optional mapping (None reads as empty) whose keys must all be ``allowed``."""
        if obj is None:
            return {}
        if not isinstance(obj, dict):
            self.fail(where, f"expected a mapping, got {type(obj).__name__} {_short(obj)}")
        for k in obj:
            if k not in allowed:
                name = f"{where}.{k}" if where else str(k)
                self.fail(name, f"unknown field (expected one of: {', '.join(allowed)})")
        return obj

    def integer(self, v, where: str, *, lo=None, hi=None) -> int:
        if isinstance(v, bool) or not isinstance(v, int):
            self.fail(where, f"expected an integer, got {_short(v)}")
        if lo is not None and v < lo:
            self.fail(where, f"expected an integer >= {lo}, got {v}")
        if hi is not None and v > hi:
            self.fail(where, f"expected an integer <= {hi}, got {v}")
        return int(v)

    def boolean(self, v, where: str) -> bool:
        if not isinstance(v, bool):
            self.fail(where, f"expected true or false, got {_short(v)}")
        return v

    def choice(self, v, where: str, options: tuple[str, ...]) -> str:
        if v not in options:
            self.fail(where, f"expected one of {', '.join(options)}, got {_short(v)}")
        return v
