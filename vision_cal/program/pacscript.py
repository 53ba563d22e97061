"""``--program pacscript``: a Denso PacScript program (``.pcs``, RC8 / RC7) for an HM/HS SCARA.

Every point is a PTP move to a joint-type value, ``Move P, @E J(j1, j2, j3, j4)`` (j1,
j2, j4 in degrees, joint 3 in mm): no inverse kinematics between the plan and the arm.
``@E`` ends each move only once the encoders are on the target (a stop at every via point
and mark, no pass motion rounding it off, so the pen output and waits follow the arrival).
The pen output is ``Set IO[n]`` / ``Reset IO[n]``; ``Delay`` (ms) settles and dwells;
``PrintDbg`` prints progress; ``Speed``, ``Accel``, ``Decel`` come from the robot file's
``program`` block. The calibrated tool (``tool_mm``) overwrites a controller tool only
when the robot file asks (``program.tool_number: n``, 1..63: ``Tool n, P(x, y, 0, 0, 0,
0)`` and ``ChangeTool n``); otherwise it is a comment. The joint moves do not use it.
``TakeArm`` / ``GiveArm`` hold the arm's semaphore.

The program is its file (``plan.pcs`` is the program ``plan``): the name follows the RC8
naming convention (a letter, then letters, digits or ``_``, at most 64, no reserved word;
:mod:`vision_cal.program.rules`), and no line passes the 1024 bytes a line may hold.
Syntax after Denso's PacScript reference and RoboDK's Denso RC8 post-processor
(``MOVE P, J(...)``); see docs/controllers.md.
"""

from __future__ import annotations

from vision_cal import __version__
from vision_cal.program.rules import RULES, check_program_name, check_tool_number, plain
from vision_cal.program.steps import (Move, Pen, Say, Wait, header_lines, optional_tool,
                                      program_steps, safe_text)

J_FMT = "{:.4f}"
Z_FMT = "{:.3f}"
TOOLS = (1, 63)   # the tool numbers a program may define (tool 0 is the flange)


def joint_value(q) -> str:
    return (f"J({J_FMT.format(q[0])}, {J_FMT.format(q[1])}, {Z_FMT.format(q[2])}, "
            f"{J_FMT.format(q[3])})")


def check(robot, name: str | None = None) -> None:
    """Refuse what PacScript cannot express: a tool number it cannot define; with ``name``
    (the output file's stem, the program's name), a name PacScript cannot take."""
    check_tool_number(robot, TOOLS, "PacScript defines tools (Tool n)")
    if name is not None:
        check_program_name("pacscript", name)


def pacscript_program(points, robot, *, title: str, tool_mm=None, name: str = "program") -> str:
    check(robot, name)
    prog = robot.program
    bit = prog.pen_output_bit
    said, tool_lines = optional_tool(
        tool_mm, prog.tool_number, comment="'", what="a tool",
        define=lambda n: [f"Tool {n}, P({tool_mm[0]:.4f}, {tool_mm[1]:.4f}, 0, 0, 0, 0)",
                          *([f"ChangeTool {n}"] if n != "n" else [])],
        defined=f"tool {prog.tool_number} (Tool, ChangeTool)")
    head = header_lines(points, robot, title=title, version=__version__,
                        joints="J(j1 deg, j2 deg, j3 mm, j4 deg)", tool=said)
    lines = [f"' {safe_text(h)}" for h in head]
    lines += ["", "Sub Main", "    TakeArm Keep = 0", "    Motor On",
              f"    Speed {plain(prog.speed_percent)}",
              f"    Accel {plain(prog.accel_percent[0])}",
              f"    Decel {plain(prog.accel_percent[1])}", *tool_lines]
    for s in program_steps(points, robot):
        if isinstance(s, Move):
            lines.append(f"    Move P, @E {joint_value(s.q)}  ' {safe_text(s.note)}")
        elif isinstance(s, Wait):
            lines.append(f"    Delay {round(1000 * s.seconds)}")
        elif isinstance(s, Pen):
            lines.append(f"    {'Set' if s.down else 'Reset'} IO[{bit}]  ' {safe_text(s.note)}")
        elif isinstance(s, Say):
            text = safe_text(s.text, banned=chr(34) + chr(39), chars=RULES["pacscript"].string_max)
            lines.append(f"    PrintDbg \"{text}\"")
    if prog.motor_off:
        lines.append("    Motor Off")
    lines += ["    GiveArm", "End Sub"]
    return "\r\n".join(lines) + "\r\n"
