"""``--program pacscript``: a Denso PacScript program (``.pcs``, RC8 / RC7) for an HM/HS SCARA.

Every point is a PTP move to a joint-type value, ``Move P, @E J(j1, j2, j3, j4)`` (j1,
j2, j4 in degrees, joint 3 in mm): no inverse kinematics between the plan and the arm.
``@E`` ends each move only once the encoders are on the target (a stop at every via point
and mark, no pass motion rounding it off, so the pen output and waits follow the arrival).
The pen output is ``Set IO[n]`` / ``Reset IO[n]``; ``Delay`` (ms) settles and dwells;
``PrintDbg`` prints progress; ``Speed``, ``Accel``, ``Decel`` come from the robot file's
``program`` block. The calibrated tool (``tool_mm``) is defined as tool 1 with
``Tool 1, P(x, y, 0, 0, 0, 0)`` and selected with ``ChangeTool 1``: the joint moves do not
use it. ``TakeArm`` / ``GiveArm`` hold the arm's semaphore. Syntax after Denso's
PacScript reference and RoboDK's Denso RC8 post-processor (``MOVE P, J(...)``); see
docs/controllers.md.
"""

from __future__ import annotations

from vision_cal import __version__
from vision_cal.program.steps import Move, Pen, Say, Wait, header_lines, program_steps, safe_text

J_FMT = "{:.4f}"
Z_FMT = "{:.3f}"


def joint_value(q) -> str:
    return (f"J({J_FMT.format(q[0])}, {J_FMT.format(q[1])}, {Z_FMT.format(q[2])}, "
            f"{J_FMT.format(q[3])})")


def pacscript_program(points, robot, *, title: str, tool_mm=None) -> str:
    prog = robot.program
    bit = prog.pen_output_bit
    head = header_lines(points, robot, title=title, version=__version__,
                        joints="J(j1 deg, j2 deg, j3 mm, j4 deg)",
                        tool=("The calibrated tool is tool 1 (Tool 1, ChangeTool 1); the joint "
                              "moves do not use it." if tool_mm is not None else
                              "No calibrated tool."))
    lines = [f"' {safe_text(h)}" for h in head]
    lines += ["", "Sub Main", "    TakeArm Keep = 0", "    Motor On",
              f"    Speed {prog.speed_percent:g}",
              f"    Accel {prog.accel_percent[0]:g}",
              f"    Decel {prog.accel_percent[1]:g}"]
    if tool_mm is not None:
        lines += [f"    Tool 1, P({tool_mm[0]:.4f}, {tool_mm[1]:.4f}, 0, 0, 0, 0)",
                  "    ChangeTool 1"]
    for s in program_steps(points, robot):
        if isinstance(s, Move):
            lines.append(f"    Move P, @E {joint_value(s.q)}  ' {safe_text(s.note)}")
        elif isinstance(s, Wait):
            lines.append(f"    Delay {round(1000 * s.seconds)}")
        elif isinstance(s, Pen):
            lines.append(f"    {'Set' if s.down else 'Reset'} IO[{bit}]  ' {safe_text(s.note)}")
        elif isinstance(s, Say):
            lines.append(f"    PrintDbg \"{safe_text(s.text, banned=chr(34) + chr(39))}\"")
    if prog.motor_off:
        lines.append("    Motor Off")
    lines += ["    GiveArm", "End Sub"]
    return "\r\n".join(lines) + "\r\n"
