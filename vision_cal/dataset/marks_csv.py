"""Marks measured by another instrument (a laser tracker, a CMM, a dial gauge): a CSV that
``vision-cal calibrate`` takes in place of a dataset folder (issue 32; docs/format.md,
"Marks from other instruments")::

    id,q1_deg,q2_deg[,q4_deg],x_mm,y_mm[,approach1,approach2][,role]

``x_mm, y_mm``: where the pen mark (or the tool point) was measured, in a right-handed
frame of the plane the arm moves in, seen from above (z up, along the joint axes): the
sheet frame of ``measured_mm``, with any origin and rotation (``base_mm`` and ``z1``
absorb them). With the robot file (``--robot``: the nominal robot block) and the
instrument's stated accuracy (``--sigma-mm``: one std per axis) it becomes the session
whose marks all carry ``measured_mm`` and ``measured_sigma_mm``: no photos, the same fit,
diagnosis and verdict, the noise floor from the stated accuracy.
"""

from __future__ import annotations

from pathlib import Path

from vision_cal.dataset.csvio import number_field, read_rows
from vision_cal.dataset.robot import load_robot_file
from vision_cal.dataset.session import FORMAT, Session, session_from_raw
from vision_cal.errors import VisionCalError

REQUIRED = ("id", "q1_deg", "q2_deg", "x_mm", "y_mm")
ROLES = ("calibration", "validation")
#: marks a CSV may hold: 4,000 poses commanded 25 times; the calibration of as many takes
#: 1.5 to 3 CPU-minutes and 1 GB (bench/speed.py --rows 100000), linear in marks
MAX_MARKS = 100_000


def session_from_marks_csv(path, robot_path, *, sigma_mm: float | None = None) -> Session:
    """The session of a marks CSV (module docstring); ``sigma_mm`` None: no stated accuracy
    (the verdict then says the residual cannot be compared with a noise floor)."""
    path = Path(path)
    if robot_path is None:
        raise VisionCalError("a marks CSV needs the robot file (--robot ROBOT.yaml): the "
                             "nominal L1, L2, zeros and base to start from", field="--robot")
    if sigma_mm is not None and not sigma_mm > 0:
        raise VisionCalError(f"expected a positive std in mm, got {sigma_mm:g}",
                             field="--sigma-mm")
    robot = load_robot_file(robot_path)
    marks, seen = [], set()
    rows = read_rows(path, REQUIRED, what="marks CSV")
    if len(rows) > MAX_MARKS:
        raise VisionCalError(f"{len(rows):,} marks: at most {MAX_MARKS:,} (a repeatability "
                             f"study of 4,000 poses x 25); calibrate from a subset, e.g. "
                             f"fewer repeats of each pose", file=str(path))
    header = set(rows[0][1]) if rows else set()
    if ("approach1" in header) != ("approach2" in header):
        raise VisionCalError("approach1 and approach2 go together", file=str(path),
                             field="line 1")
    for line, row in rows:
        mid = row["id"]
        if not mid:
            raise VisionCalError("empty id", file=str(path), field=f"line {line}: id")
        if mid in seen:
            raise VisionCalError(f"duplicate id {mid!r}", file=str(path),
                                 field=f"line {line}: id")
        seen.add(mid)

        def num(k):
            return number_field(row[k], path, line, k)

        m = {"id": mid, "joints_deg": [num("q1_deg"), num("q2_deg")],
             "measured_mm": [num("x_mm"), num("y_mm")]}
        if row.get("q4_deg"):
            m["j4_deg"] = num("q4_deg")
        if row.get("approach1") or row.get("approach2"):
            a = [num("approach1"), num("approach2")]
            if any(v not in (1.0, -1.0) for v in a):
                raise VisionCalError(f"expected +1 or -1, got {a}", file=str(path),
                                     field=f"line {line}: approach1, approach2")
            m["approach"] = [int(v) for v in a]
        if row.get("role"):
            if row["role"] not in ROLES:
                raise VisionCalError(f"expected one of {', '.join(ROLES)}, got {row['role']!r}",
                                     file=str(path), field=f"line {line}: role")
            m["role"] = row["role"]
        if sigma_mm is not None:
            m["measured_sigma_mm"] = float(sigma_mm)
        marks.append(m)
    if not marks:
        raise VisionCalError("no marks", file=str(path))
    raw = {"format": FORMAT, "robot": robot.nominal.to_json(), "marks": marks, "images": [],
           "source": {"marks_csv": str(path), "robot": str(robot_path),
                      "sigma_mm": sigma_mm}}
    return session_from_raw(raw, path.parent, str(path))
