"""Robot programs from a plan: the points a controller drives through, in order.

:func:`program_points` turns planned marks (``PlannedMark``: joints, approach, overshoot
via points) into the ordered point list every writer shares: home, then for each mark its
via points and the mark, then home again. Writers:

- :mod:`vision_cal.program.csv_list` (``--program csv``): a neutral point list any
  controller's import can take;
- :mod:`vision_cal.program.spel` (``--program spel``): an Epson SPEL+ program;
- :mod:`vision_cal.program.rapid` (``--program rapid``): an ABB RAPID module;
- :mod:`vision_cal.program.val3` (``--program val3``): a Staubli VAL3 application (a folder:
  ``.pjx``, ``.dtx``, ``start.pgx``, ``stop.pgx``);
- :mod:`vision_cal.program.evplus` (``--program evplus``): an Omron/Adept eV+ program;
- :mod:`vision_cal.program.pacscript` (``--program pacscript``): a Denso PacScript program;
- :mod:`vision_cal.program.fanuc_tp` (``--program tp``): a Fanuc TP program (ASCII ``.ls``).

The other controllers' writers share the steps of :mod:`vision_cal.program.steps`; each
writes joint targets only (docs/controllers.md). Programs, modules and applications are
named after their output file, checked (with ``pen_signal``) against each language's rules
of :mod:`vision_cal.program.rules`; the travel height is checked against joint 3's travel
and the pen heights (``RobotFile.check_travel_height``).

Joint 3 (the vertical axis of a SCARA) is in millimetres, joints 1, 2 and 4 in degrees.
The pen travels at ``pen_up_mm`` and marks at ``pen_down_mm`` (the robot file).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vision_cal.dataset.io import atomic_write_text, written_together
from vision_cal.errors import VisionCalError
from vision_cal.program.csv_list import point_list
from vision_cal.program import evplus, fanuc_tp, pacscript, rapid, spel, val3
from vision_cal.program.evplus import evplus_program
from vision_cal.program.fanuc_tp import tp_program
from vision_cal.program.pacscript import pacscript_program
from vision_cal.program.rapid import rapid_program
from vision_cal.program.spel import spel_program
from vision_cal.program.val3 import val3_application

# kind -> (writer, suffix of the program file); csv is a point list, not a program. A
# writer returns the file's text, or (VAL3) the files of an application folder
WRITERS = {"spel": (spel_program, ".prg"), "rapid": (rapid_program, ".mod"),
           "val3": (val3_application, ".pjx"),
           "evplus": (evplus_program, ".v2"), "pacscript": (pacscript_program, ".pcs"),
           "tp": (tp_program, ".ls")}
KINDS = ("csv", *WRITERS)
# kind -> its refusal of robot files (and, given, program names) it cannot express
CHECKS = {"spel": spel.check, "rapid": rapid.check, "val3": val3.check,
          "evplus": evplus.check, "pacscript": pacscript.check, "tp": fanuc_tp.check}


def check_program(kind: str, robot, name: str | None = None) -> None:
    """Everything a program of ``kind`` needs from the robot file, checked before any output
    is written: the pen heights, the travel height, and what the dialect can express (its
    ``check``; with ``name``, the program's name, its output file's stem, too)."""
    robot.require_pen_heights()
    robot.check_travel_height()
    if kind in CHECKS:
        CHECKS[kind](robot, name)


@dataclass(frozen=True)
class ProgramPoint:
    id: str                      # the mark's id ("home" for home)
    kind: str                    # "home" | "via" | "mark"
    q_deg: tuple[float, float]   # joints 1 and 2
    elbow: int                   # +1: sin(q2 + z2) > 0
    approach: tuple[int, int] | None = None   # the mark's planned approach signs
    role: str = ""
    q4_deg: float | None = None  # joint 4 (None: the robot file's j4_deg)


def elbow_of(q2_deg, z2_deg: float) -> int:
    """+1 when sin(q2 + z2) > 0 (docs/conventions.md), else -1."""
    return 1 if np.sin(np.radians(float(q2_deg) + float(z2_deg))) > 0 else -1


def program_points(marks, *, home_deg=(0.0, 0.0), z2_deg: float = 0.0,
                   joint4: dict | None = None) -> list[ProgramPoint]:
    """Home, each mark's via points then the mark (drawing order), home. ``joint4``
    (optional): mark id -> (q4 at the mark, q4 at its via points), deg, for plans that
    turn joint 4 (:mod:`vision_cal.plan.orient`)."""
    home = (float(home_deg[0]), float(home_deg[1]))
    out = [ProgramPoint("home", "home", home, elbow_of(home[1], z2_deg))]
    for m in marks:
        a = tuple(int(v) for v in m.approach) if m.approach is not None else None
        q4, q4_via = (joint4 or {}).get(m.id, (None, None))
        for v in m.via_deg:
            q = (float(v[0]), float(v[1]))
            out.append(ProgramPoint(m.id, "via", q, elbow_of(q[1], z2_deg), a, m.role, q4_via))
        q = (float(m.joints_deg[0]), float(m.joints_deg[1]))
        out.append(ProgramPoint(m.id, "mark", q, elbow_of(q[1], z2_deg), a, m.role, q4))
    out.append(ProgramPoint("home", "home", home, elbow_of(home[1], z2_deg)))
    if not all(np.isfinite(p.q_deg).all() for p in out):
        raise VisionCalError("a program point is not a finite number", field="marks")
    return out


def program_path(kind: str, stem) -> Path:
    """Where a program of ``kind`` goes, beside ``stem`` (a path without its suffix); a
    VAL3 application is a folder ``stem/`` and this is its project file ``stem/stem.pjx``."""
    stem = Path(stem)
    if kind == "val3":
        return stem / (stem.name + WRITERS[kind][1])
    if kind in WRITERS:   # the suffix added (a stem with a dot keeps its name)
        return stem.with_name(stem.name + WRITERS[kind][1])
    if kind == "csv":
        return stem.with_name(stem.name + "_points.csv")
    raise VisionCalError(f"unknown program kind {kind!r} (expected one of {', '.join(KINDS)})",
                         field="--program")


def write_program(kind: str, path, points, robot, *, title: str, tool_mm=None) -> Path:
    """Write the program of ``kind`` (one of :data:`KINDS`) for ``points`` to ``path``;
    ``tool_mm`` (programs, not csv): the calibrated tool, written as the program's own data
    (RAPID ``tooldata``, VAL3 ``tool``) or, when the robot file names
    ``program.tool_number``, as that controller tool (SPEL+ ``TLSet``, PacScript ``Tool``,
    eV+ ``TOOL``); otherwise as a comment. The program (module, application) is named
    after ``path``'s stem. A program a dialect cannot express is refused
    (:class:`VisionCalError` naming the robot file's field, or ``--program`` for the name)
    before anything is written. A VAL3 application's files go into ``path``'s folder;
    ``path`` (its ``.pjx``) is returned."""
    path = Path(path)
    if kind == "csv":
        check_program(kind, robot)
        return atomic_write_text(path, point_list(points, robot))
    if kind not in WRITERS:
        raise VisionCalError(f"unknown program kind {kind!r} (expected one of "
                             f"{', '.join(KINDS)})", field="--program")
    check_program(kind, robot, path.stem)  # before anything is written
    out = WRITERS[kind][0](points, robot, title=title, tool_mm=tool_mm, name=path.stem)
    if isinstance(out, str):
        return atomic_write_text(path, out)
    with written_together():   # an application: its files, all or none
        for file_name, text in out.items():
            atomic_write_text(path.parent / file_name, text)
    return path
