"""``--program val3``: a Staubli VAL3 program (one ``.pgx`` file) for a TS2 SCARA (CS9).

A VAL3 application is a folder (``.pjx`` project, ``.dtx`` data, one ``.pgx`` per
program); this writes the one program that draws the plan, to add to an application
(SRS / Stäubli Robotics Suite: add an existing program, and call it from ``start``). Its
name is the file's stem (``plan.pgx``: ``call plan()``).

Every point is a joint move ``movej(l_j, flange, l_m)`` to a local ``joint`` variable
(VAL3 s7 and later, the CS9's s8: ``joint``; CS8 applications name the type ``jointRx``)
whose fields are set just before (``l_j.j1 = ...`` .. ``l_j.j4``: degrees, joint 3 of the
SCARA in mm): no inverse kinematics between the plan and the arm. VAL3 queues moves ahead
of the arm: ``waitEndMove()`` after every ``movej`` waits for the arm to stand on the
point (and ``l_m.blend = off`` keeps via points from being rounded off), so the pen output
and the waits follow the arrival. The motion descriptor ``l_m`` (local ``mdesc``) takes
``speed_percent`` (``vel``) and ``accel_percent`` (``accel``, ``decel``). The pen output
is a global ``dio`` of the application named ``program.pen_signal`` (``doPen = true`` /
``false``); without that name the writer refuses. ``delay(s)`` settles and dwells,
``putln`` prints progress, ``motor_off`` becomes ``disablePower()``. The moves name the
predefined tool ``flange``; the calibrated tool (``tool_mm``) is written as comments to
enter as the application's tool data (a joint move does not go through it). Syntax after
Stäubli's VAL3 reference manual and RoboDK's Stäubli VAL3 post-processors (``.pgx``
layout, ``<Locals>``, ``movej``, ``waitEndMove``); see docs/controllers.md.
"""

from __future__ import annotations

import re

from vision_cal import __version__
from vision_cal.errors import VisionCalError
from vision_cal.program.steps import Move, Pen, Say, Wait, header_lines, program_steps, safe_text

J_FMT = "{:.4f}"
Z_FMT = "{:.3f}"
NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,14}")
BANNED = '"<>&]'   # nothing that ends a VAL3 string, the CDATA section or the XML


def check(robot) -> None:
    """Refuse what VAL3 cannot express: a pen output without its ``dio``'s name."""
    prog = robot.program
    if prog.pen_output_bit is not None and prog.pen_signal is None:
        raise VisionCalError("missing: VAL3 sets an output through a dio variable; give its "
                             f"name (the pen's output, bit {prog.pen_output_bit}) as "
                             "program.pen_signal", file=str(robot.path),
                             field="program.pen_signal")


def val3_program(points, robot, *, title: str, tool_mm=None, name: str = "visionCal") -> str:
    check(robot)
    if not NAME.fullmatch(name):
        raise VisionCalError(f"a VAL3 program is named after its file: {name!r} is not a VAL3 "
                             "name (a letter, then letters, digits or _, at most 15); choose "
                             "another output name", field="--program")
    prog = robot.program
    head = header_lines(points, robot, title=title, version=__version__,
                        joints="movej to joint values: j1, j2, j4 deg, j3 mm",
                        tool=(f"The calibrated tool: x {tool_mm[0]:.4f} mm, y {tool_mm[1]:.4f} "
                              "mm in the flange frame: enter it as the application's tool; the "
                              "joint moves name flange and do not use it." if tool_mm is not None
                              else "No calibrated tool: the moves name flange."))
    code = ["begin"] + [f"  // {safe_text(h, banned=BANNED)}" for h in head]
    code += [f"  l_m.vel = {prog.speed_percent:g}", f"  l_m.accel = {prog.accel_percent[0]:g}",
             f"  l_m.decel = {prog.accel_percent[1]:g}", "  l_m.blend = off"]
    for s in program_steps(points, robot):
        if isinstance(s, Move):
            q = s.q
            code += [f"  // {safe_text(s.note, banned=BANNED)}",
                     f"  l_j.j1 = {J_FMT.format(q[0])}", f"  l_j.j2 = {J_FMT.format(q[1])}",
                     f"  l_j.j3 = {Z_FMT.format(q[2])}", f"  l_j.j4 = {J_FMT.format(q[3])}",
                     "  movej(l_j, flange, l_m)", "  waitEndMove()"]
        elif isinstance(s, Wait):
            code.append(f"  delay({s.seconds:g})")
        elif isinstance(s, Pen):
            code.append(f"  {prog.pen_signal} = {'true' if s.down else 'false'}"
                        f"  // {safe_text(s.note, banned=BANNED)}")
        elif isinstance(s, Say):
            code.append(f"  putln(\"{safe_text(s.text, banned=BANNED + '/')}\")")
    if prog.motor_off:
        code.append("  disablePower()")
    code.append("end")
    return "\n".join([
        '<?xml version="1.0" encoding="utf-8"?>',
        '<Programs xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" '
        'xmlns="http://www.staubli.com/robotics/VAL3/Program/2">',
        f'  <Program name="{name}" access="public">',
        "    <Locals>",
        '      <Local name="l_j" type="joint" xsi:type="array" size="1" />',
        '      <Local name="l_m" type="mdesc" xsi:type="array" size="1" />',
        "    </Locals>",
        "    <Code><![CDATA[" + "\n".join(code) + "]]></Code>",
        "  </Program>",
        "</Programs>", ""])
