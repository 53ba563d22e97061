"""The steps every controller's program takes, whatever its language.

:func:`program_steps` turns the shared point list (:func:`vision_cal.program.program_points`)
and the robot file's ``program`` block into a flat list of steps, the same for every
dialect (``rapid``, ``evplus``, ``pacscript``, ``tp``), so the dialects differ only in how
they spell a step:

- :class:`Move`: a point-to-point joint move to (j1, j2, j3, j4): degrees, joint 3 in mm.
  Each joint moves monotonically from start to end in a joint move, so the last motion of
  a joint onto a mark has the sign of mark minus via point (the planned approach side).
- :class:`Pen`: the pen output on (pen down) or off (pen up), when the robot file names
  ``pen_output_bit``; otherwise the pen goes down and up as joint 3 moves.
- :class:`Wait`: settle on the mark / pen dwell, seconds.
- :class:`Say`: a progress message ("mark A3 (4 of 40)").

Travel to home and to each mark's first point: with ``safe_z_mm`` joint 3 rises to the
safe height where the arm is, the arm moves at that height, joint 3 comes down (three
joint moves: the SPEL+ ``Jump ... LimZ`` spelled out); the last move onto a mark is always
a plain joint move from its via point.
"""

from __future__ import annotations

import logging
import textwrap
from dataclasses import dataclass

from vision_cal.program.rules import plain, short_id

log = logging.getLogger(__name__)

#: the characters of one line of the opening comment block (a long title is wrapped)
HEADER_CHARS = 120


@dataclass(frozen=True)
class Move:
    q: tuple[float, float, float, float]   # j1 deg, j2 deg, j3 mm, j4 deg
    note: str                              # "home", "A3 via", "A3 mark", "A3 pen down", ...
    kind: str                              # "home" | "via" | "mark" | "pen" | "travel"


@dataclass(frozen=True)
class Pen:
    down: bool
    note: str


@dataclass(frozen=True)
class Wait:
    seconds: float


@dataclass(frozen=True)
class Say:
    text: str


def safe_text(text, *, banned: str = '"', chars: int | None = None) -> str:
    """Text that cannot end a string or a line of any dialect (ids come from the user's
    targets.csv): printable ASCII only, ``banned`` characters replaced by ``_``; with
    ``chars``, at most that many characters (a longer text cut, ending in ``~``)."""
    out = "".join(c if c.isprintable() and c.isascii() and c not in banned else "_"
                  for c in str(text))
    if chars is not None and len(out) > chars:
        out = out[:chars - 1] + "~"
    return out


def optional_tool(tool_mm, number, *, define, comment: str, what: str,
                  defined: str) -> tuple[str, list[str]]:
    """(the header's sentence on the calibrated tool, the program's lines for it).
    ``define(n)``: the statements that make it controller tool ``n``, written only when the
    robot file names ``program.tool_number`` (``number``); otherwise the first of them,
    for tool ``"n"``, as a comment (``comment``: the language's marker), so no controller
    tool is overwritten unasked. ``what``: the tool it would become; ``defined``: how."""
    if tool_mm is None:
        return "No calibrated tool.", []
    if number is None:
        return (f"The calibrated tool is a comment below (give program.tool_number in the "
                f"robot file to define it as {what}).", [f"    {comment} {define('n')[0]}"])
    return (f"The calibrated tool is {defined}; the joint moves do not use it.",
            [f"    {s}" for s in define(number)])


def whole_percent(x: float, *, robot, field: str, language: str, lo: int = 1) -> int:
    """``x`` % as a language that takes whole percent (``lo``..100) writes it; a value
    that changes is said (one warning naming the robot file's field), never silently."""
    n = max(lo, min(100, round(float(x))))
    if n != x:
        log.warning("%s: %s: %s %% is written as %d %% (%s takes %d..100 whole percent)",
                    robot.path, field, plain(x), n, language, lo)
    return n


def program_steps(points, robot) -> list:
    """The steps that drive ``points`` (home, via points, marks, home) with the robot
    file's pen heights, settle, dwell, pen output and safe height."""
    up, down = robot.require_pen_heights()
    prog = robot.program
    bit, safe = prog.pen_output_bit, prog.safe_z_mm
    n_marks = sum(1 for p in points if p.kind == "mark")
    out: list = []
    here = None          # (j1, j2, j4) where the arm is, once known
    announced, k, first = None, 0, True

    def travel(q4, p, note):
        if safe is not None:
            if here is not None:
                out.append(Move((here[0], here[1], float(safe), here[2]), "rise to the safe "
                                "height", "travel"))
            out.append(Move((p.q_deg[0], p.q_deg[1], float(safe), q4), f"{note} at the safe "
                            "height", "travel"))
        out.append(Move((p.q_deg[0], p.q_deg[1], up, q4), note, p.kind))

    for p in points:
        q4 = robot.j4_deg if p.q4_deg is None else float(p.q4_deg)
        pid = short_id(p.id)
        if p.kind != "home" and p.id != announced:
            announced, first = p.id, True
            k += 1
            out.append(Say(f"mark {pid} ({k} of {n_marks})"))
        if p.kind == "home":
            travel(q4, p, "home")
        elif p.kind == "via":
            if first:
                travel(q4, p, f"{pid} via")
            else:
                out.append(Move((p.q_deg[0], p.q_deg[1], up, q4), f"{pid} via", "via"))
            first = False
        else:
            a = p.approach or (0, 0)
            out.append(Move((p.q_deg[0], p.q_deg[1], up, q4), f"{pid} mark, approach "
                            f"{a[0]:+d} {a[1]:+d}, elbow {p.elbow:+d}", "mark"))
            if prog.settle_s > 0:
                out.append(Wait(prog.settle_s))
            if bit is None:
                out.append(Move((p.q_deg[0], p.q_deg[1], down, q4), f"{pid} pen down", "pen"))
            else:
                out.append(Pen(True, f"{pid} pen down"))
            if prog.pen_dwell_s > 0:
                out.append(Wait(prog.pen_dwell_s))
            if bit is None:
                out.append(Move((p.q_deg[0], p.q_deg[1], up, q4), f"{pid} pen up", "pen"))
            else:
                out.append(Pen(False, f"{pid} pen up"))
        here = (p.q_deg[0], p.q_deg[1], q4)
    out.append(Say(f"done: {n_marks} marks"))
    return out


def header_lines(points, robot, *, title: str, version: str, joints: str, tool: str) -> list[str]:
    """The comment block every dialect opens with (plain text; the dialect adds its comment
    marker): what the program does, the joint units as that controller writes them
    (``joints``) and what it does with the tool (``tool``)."""
    up, down = robot.require_pen_heights()
    prog = robot.program
    n = sum(1 for p in points if p.kind == "mark")
    calibration = any(p.role in ("calibration", "validation") for p in points if p.kind == "mark")
    bit = prog.pen_output_bit
    dwell = plain(prog.pen_dwell_s)
    lines = [
        title,
        f"robot {safe_text(robot.name, chars=60)}: {n} marks; generated by vision-cal {version}",
        f"Every point is a joint target ({joints}): no controller inverse",
        "kinematics between the plan and the arm. Each mark is approached through its",
        "overshoot via point so that each joint arrives from the planned side; then the pen",
        (f"goes down (joint 3 to {down:.3f} mm), dwells {dwell} s and goes up "
         f"({up:.3f} mm)." if bit is None else
         f"goes down (output {bit} on), dwells {dwell} s and goes up (output "
         f"{bit} off); joint 3 stays at {up:.3f} mm."),
        "Joint 3 values are the robot file's pen heights as they are: set them in this",
        "controller's joint 3 convention (sign, zero).",
        tool,
        ("Do not edit the points: the calibration reads the commanded joints from "
         "session.json." if calibration else
         "Edit no point: each was planned with the calibrated model, its approach side "
         "included."),
        "Start with the pen up and the arm clear of the sheet.",
    ]
    # a long title (a long targets path, extrapolations named) as lines of HEADER_CHARS
    return [w for line in lines for w in (textwrap.wrap(line, HEADER_CHARS) or [""])]
