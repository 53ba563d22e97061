"""Targets and planned joints (CSV), as docs/format.md says::

    targets.csv:  id,x_mm,y_mm
    plan.csv:     id,q1_deg,q2_deg,approach1,approach2

Extra columns may follow the listed ones (``status``, ``reason``, ``predicted_x_mm`` ...);
readers ignore the columns they do not know.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from vision_cal.dataset.io import atomic_write_text, expected, read_text
from vision_cal.errors import VisionCalError

TARGET_FIELDS = ("id", "x_mm", "y_mm")
PLAN_FIELDS = ("id", "q1_deg", "q2_deg", "approach1", "approach2")


#: The longest field read (bytes): a stray quote makes the rest of the file one field.
MAX_FIELD_CHARS = 4096


def _rows(path: Path, required: tuple[str, ...],
          what: str = "CSV file") -> list[tuple[int, dict]]:
    """Rows as dicts with their line number. A row with more fields than the header (an
    unquoted decimal comma: ``a,100,5,250``), a field running over a line end or longer than
    :data:`MAX_FIELD_CHARS` (a stray quote), a column named twice in the header is refused
    naming the line: never read as something else. ``what``: the kind of CSV (a key of
    :data:`vision_cal.dataset.io.EXPECTED`), said when a JSON document is given instead."""
    text = read_text(path, what=what)
    if text.lstrip().startswith(("{", "[")):   # a calibration.json given for a targets CSV
        raise VisionCalError(f"is JSON, expected {expected(what)}", file=str(path))
    reader = csv.reader(io.StringIO(text))
    try:
        rows = []
        start = 1
        for row in reader:
            rows.append((start, row))
            if any(len(v) > MAX_FIELD_CHARS or "\n" in v or "\r" in v for v in row):
                raise VisionCalError(
                    "a field runs over the line end (a stray quote \")", file=str(path),
                    field=f"line {start}")
            start = reader.line_num + 1
    except csv.Error as e:
        raise VisionCalError(f"not valid CSV ({e}; a stray quote \"?)", file=str(path),
                             field=f"line {start}") from e
    if not rows:
        header = []
    else:
        header = [h.strip() for h in rows[0][1]]
    _refuse_duplicate_columns(header, path)
    missing = [f for f in required if f not in header]
    if missing:
        raise VisionCalError(f"header lacks {', '.join(missing)} (expected {','.join(required)})",
                             file=str(path), field="line 1")
    out = []
    for line, row in rows[1:]:
        if not row:  # a blank line
            continue
        if len(row) > len(header):
            raise VisionCalError(
                f"{len(row)} fields but the header has {len(header)} (a decimal comma? "
                "write 100.5, or quote the field)", file=str(path), field=f"line {line}")
        out.append((line, {k: v.strip() for k, v in zip(header, row) if k}
                    | {k: "" for k in header[len(row):] if k}))
    return out


def _refuse_duplicate_columns(header: list[str], path: Path) -> None:
    """A column named twice is refused naming both (a dict of the row would silently keep
    the last one: a target planned at the wrong x, a marks CSV with every x 0)."""
    for i, name in enumerate(header):
        if name and name in header[:i]:
            raise VisionCalError(f"column {name!r} is given twice (columns "
                                 f"{header.index(name) + 1} and {i + 1}); keep one",
                                 file=str(path), field="line 1")


def read_rows(path, required: tuple[str, ...], *,
              what: str = "CSV file") -> list[tuple[int, dict]]:
    """Every CSV reader's rows (dicts with their line number), checked as :func:`_rows`
    says (a stray quote, a decimal comma, a missing column, a column named twice: one line
    naming it)."""
    return _rows(Path(path), required, what)


def number_field(v: str, path, line: int, name: str) -> float:
    """A finite number from a CSV cell, or one line naming the file, the line and the
    column."""
    try:
        x = float(v)
    except ValueError as e:
        raise VisionCalError(f"expected a number, got {v!r}", file=str(path),
                             field=f"line {line}: {name}") from e
    if not math.isfinite(x):
        raise VisionCalError(f"expected a finite number, got {v!r}", file=str(path),
                             field=f"line {line}: {name}")
    return x


def read_targets(path) -> tuple[list[str], np.ndarray]:
    """Target ids and sheet positions (N, 2) mm."""
    ids, xy, seen = [], [], set()
    for line, row in _rows(path, TARGET_FIELDS, "targets CSV"):
        tid = row["id"]
        if not tid:
            raise VisionCalError("empty id", file=str(path), field=f"line {line}: id")
        if tid in seen:
            raise VisionCalError(f"duplicate id {tid!r}", file=str(path), field=f"line {line}: id")
        seen.add(tid)
        ids.append(tid)
        xy.append((number_field(row["x_mm"], path, line, "x_mm"), number_field(row["y_mm"], path, line, "y_mm")))
    if not ids:
        raise VisionCalError("no targets", file=str(path))
    return ids, np.array(xy, dtype=float)


def write_targets(path, ids, xy_mm) -> Path:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(TARGET_FIELDS)
    for i, (x, y) in zip(ids, np.asarray(xy_mm, dtype=float)):
        w.writerow([i, f"{x:.4f}", f"{y:.4f}"])
    return atomic_write_text(path, buf.getvalue())


def write_plan(path, rows: list[dict]) -> Path:
    """Rows with the plan fields plus any extra columns (same keys in every row)."""
    extra = [k for k in (rows[0] if rows else {}) if k not in PLAN_FIELDS]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(PLAN_FIELDS) + extra, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{v:.9f}" if isinstance(v, float) else v) for k, v in r.items()})
    return atomic_write_text(path, buf.getvalue())


FAILED_FIELDS = ("id", "x_mm", "y_mm", "reason")


def failed_report_path(plan_path) -> Path:
    """Where ``plan`` reports the targets it could not plan: ``PLAN.failed.csv`` beside it."""
    p = Path(plan_path)
    return p.with_name(f"{p.stem}.failed.csv")


def write_failed_targets(path, rows) -> Path:
    """Targets that were not planned: (id, x_mm, y_mm, reason) each."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(FAILED_FIELDS)
    for tid, x, y, why in rows:
        w.writerow([tid, f"{x:.4f}", f"{y:.4f}", why])
    return atomic_write_text(path, buf.getvalue())


def read_plan(path) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Planned ids, joints (N, 2) deg and approach signs (N, 2); rows with a failed
    ``status`` (not planned) are skipped."""
    ids, q, s = [], [], []
    for line, row in _rows(path, PLAN_FIELDS, "plan CSV"):
        if row.get("status", "ok") not in ("", "ok"):
            continue
        ids.append(row["id"])
        q.append((number_field(row["q1_deg"], path, line, "q1_deg"), number_field(row["q2_deg"], path, line, "q2_deg")))
        a = (number_field(row["approach1"], path, line, "approach1"),
             number_field(row["approach2"], path, line, "approach2"))
        if any(v not in (1.0, -1.0) for v in a):
            raise VisionCalError(f"expected +1 or -1, got {a}", file=str(path),
                                 field=f"line {line}: approach")
        s.append(a)
    return ids, np.array(q, float).reshape(-1, 2), np.array(s, float).reshape(-1, 2)


def read_target_theta(path) -> np.ndarray | None:
    """The optional ``theta_deg`` column of targets.csv (N,) - the tool's orientation in the
    sheet frame (docs/format.md) - or None when the file has no such column."""
    rows = _rows(path, TARGET_FIELDS, "targets CSV")
    if not rows or "theta_deg" not in rows[0][1]:
        return None
    return np.array([number_field(row["theta_deg"], path, line, "theta_deg") for line, row in rows])
