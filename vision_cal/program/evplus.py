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
(``tool_mm``) replaces the robot's current tool (``TOOL TRANS(x, y, 0, 0, 0, 0)``, in effect
after the program ends) only when the robot file asks (``program.tool_number``, any number:
eV+ has one current tool); otherwise it is a comment. The joint moves do not use it.

The program is named after its file (``plan.v2``: ``.PROGRAM plan()``), so a second plan
loads beside the first; the name follows the V+ Language User's Guide (a letter, then
letters, digits, ``.`` or ``_``, at most 15 significant characters, no keyword) and every
``TYPE`` string keeps within its 128 characters (mark ids are cut, ``rules.ID_CHARS``).
Syntax after the eV+ Language Reference (MOVE, #PPOINT, BREAK, FINE, SIGNAL, DELAY, TYPE,
SPEED, ACCEL, TOOL, TRANS); see docs/controllers.md.
"""

from __future__ import annotations

from vision_cal import __version__
from vision_cal.errors import VisionCalError
from vision_cal.program.rules import RULES, check_program_name, plain
from vision_cal.program.steps import (Move, Pen, Say, Wait, header_lines, optional_tool,
                                      program_steps, safe_text)

J_FMT = "{:.4f}"
Z_FMT = "{:.3f}"


def ppoint(q) -> str:
    return (f"#PPOINT({J_FMT.format(q[0])}, {J_FMT.format(q[1])}, {Z_FMT.format(q[2])}, "
            f"{J_FMT.format(q[3])})")


def check(robot, name: str | None = None) -> None:
    """Refuse what eV+ cannot express: output 0 (``SIGNAL -0`` cannot switch it off); with
    ``name`` (the output file's stem), a program name eV+ cannot take."""
    if robot.program.pen_output_bit == 0:
        raise VisionCalError("eV+ switches an output off with SIGNAL -n, so output 0 cannot "
                             "be switched off; give the pen's output number (1 and up)",
                             file=str(robot.path), field="program.pen_output_bit")
    if name is not None:
        check_program_name("evplus", name)


def evplus_program(points, robot, *, title: str, tool_mm=None, name: str = "program") -> str:
    check(robot, name)
    prog = robot.program
    bit = prog.pen_output_bit
    said, tool_lines = optional_tool(
        tool_mm, prog.tool_number, comment=";", what="the robot's TOOL",
        define=lambda n: [f"TOOL TRANS({tool_mm[0]:.4f}, {tool_mm[1]:.4f}, 0, 0, 0, 0)"],
        defined="set with TOOL")
    head = header_lines(points, robot, title=title, version=__version__,
                        joints="precision points #PPOINT(j1 deg, j2 deg, j3 mm, j4 deg)",
                        tool=said)
    lines = [f".PROGRAM {name}()"]
    lines += [f"    ; {safe_text(h)}" for h in head]
    lines += [f"    SPEED {plain(prog.speed_percent)} ALWAYS",
              f"    ACCEL {plain(prog.accel_percent[0])}, {plain(prog.accel_percent[1])}",
              "    FINE ALWAYS", *tool_lines]
    for s in program_steps(points, robot):
        if isinstance(s, Move):
            lines += [f"    MOVE {ppoint(s.q)}    ; {safe_text(s.note)}", "    BREAK"]
        elif isinstance(s, Wait):
            lines.append(f"    DELAY {plain(s.seconds)}")
        elif isinstance(s, Pen):
            lines.append(f"    SIGNAL {bit if s.down else -bit}    ; {safe_text(s.note)}")
        elif isinstance(s, Say):
            text = safe_text(s.text, banned=chr(34) + ";", chars=RULES["evplus"].string_max)
            lines.append(f"    TYPE \"{text}\"")
    if prog.motor_off:
        lines.append("    DISABLE POWER")
    lines.append(".END")
    return "\n".join(lines) + "\n"
