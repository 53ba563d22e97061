"""``--program evplus``: an Omron/Adept eV+ (V+) program for a Cobra-type SCARA (``.v2``,
the default extension of ``LOAD`` and ``STORE``).

Every point is a precision point, ``MOVE #PPOINT(j1, j2, j3, j4)`` (joint values: j1, j2,
j4 in degrees, joint 3 in mm), a joint-interpolated move that no inverse kinematics
touches. eV+ runs the program ahead of the arm: ``BREAK`` after every move waits until the
arm has arrived (and keeps moves from blending, so a via point is passed exactly), and
``FINE ALWAYS`` asks for the tight arrival tolerance. The pen output is ``SIGNAL n`` (on)
and ``SIGNAL -n`` (off); an output 0 cannot be switched off that way, so the writer
refuses it. ``DELAY s`` settles and dwells, ``TYPE`` prints progress, ``SPEED n ALWAYS``
and ``ACCEL a, d`` come from the robot file's ``program`` block. The calibrated tool
(``tool_mm``) is set with ``TOOL TRANS(x, y, 0, 0, 0, 0)``: the joint moves do not use it.
Syntax after the eV+ Language Reference (MOVE, #PPOINT, BREAK, FINE, SIGNAL, DELAY, TYPE,
SPEED, ACCEL, TOOL, TRANS); see docs/controllers.md.
"""

from __future__ import annotations

from vision_cal import __version__
from vision_cal.errors import VisionCalError
from vision_cal.program.steps import Move, Pen, Say, Wait, header_lines, program_steps, safe_text

J_FMT = "{:.4f}"
Z_FMT = "{:.3f}"


def ppoint(q) -> str:
    return (f"#PPOINT({J_FMT.format(q[0])}, {J_FMT.format(q[1])}, {Z_FMT.format(q[2])}, "
            f"{J_FMT.format(q[3])})")


def check(robot) -> None:
    """Refuse what eV+ cannot express: output 0 (``SIGNAL -0`` cannot switch it off)."""
    if robot.program.pen_output_bit == 0:
        raise VisionCalError("eV+ switches an output off with SIGNAL -n, so output 0 cannot "
                             "be switched off; give the pen's output number (1 and up)",
                             file=str(robot.path), field="program.pen_output_bit")


def evplus_program(points, robot, *, title: str, tool_mm=None) -> str:
    check(robot)
    prog = robot.program
    bit = prog.pen_output_bit
    head = header_lines(points, robot, title=title, version=__version__,
                        joints="precision points #PPOINT(j1 deg, j2 deg, j3 mm, j4 deg)",
                        tool=("The calibrated tool is set with TOOL; the joint moves do not "
                              "use it." if tool_mm is not None else "No calibrated tool."))
    lines = [".PROGRAM vision_cal()"]
    lines += [f"    ; {safe_text(h)}" for h in head]
    lines += [f"    SPEED {prog.speed_percent:g} ALWAYS",
              f"    ACCEL {prog.accel_percent[0]:g}, {prog.accel_percent[1]:g}",
              "    FINE ALWAYS"]
    if tool_mm is not None:
        lines.append(f"    TOOL TRANS({tool_mm[0]:.4f}, {tool_mm[1]:.4f}, 0, 0, 0, 0)")
    for s in program_steps(points, robot):
        if isinstance(s, Move):
            lines += [f"    MOVE {ppoint(s.q)}    ; {safe_text(s.note)}", "    BREAK"]
        elif isinstance(s, Wait):
            lines.append(f"    DELAY {s.seconds:g}")
        elif isinstance(s, Pen):
            lines.append(f"    SIGNAL {bit if s.down else -bit}    ; {safe_text(s.note)}")
        elif isinstance(s, Say):
            lines.append(f"    TYPE \"{safe_text(s.text, banned=chr(34) + ';')}\"")
    if prog.motor_off:
        lines.append("    DISABLE POWER")
    lines.append(".END")
    return "\n".join(lines) + "\n"
