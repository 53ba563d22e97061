"""``--program val3``: a Staubli VAL3 application for a TS2 SCARA (CS9), as SRS and the
controller load it: a folder named after the output file holding

- ``NAME.pjx``: the project (VAL3 version, stack, millimetre units), listing its programs
  and its data file;
- ``NAME.dtx``: the application's data: the pen output, a global ``dio`` named
  ``program.pen_signal`` linked to ``BasicIO-1\\%Q<pen_output_bit>`` (the controller's
  basic I/O board: relink it in SRS when the pen is wired elsewhere), and the calibrated
  tool ``tPen`` (``tool_mm``, fathered by ``flange``);
- ``start.pgx``: the program the controller runs when the application starts: it draws the
  plan;
- ``stop.pgx``: run when the application stops: ``resetMotion()`` drops the queued moves
  and the pen goes up.

Layout after public applications (ROS-Industrial's ``staubli_val3_driver``
``val3/ros_server``: ``ros_server.pjx``, ``ros_server.dtx``, ``start.pgx``, ``stop.pgx``)
and RoboDK's Staubli VAL3 post-processors. Copy the folder to the controller's
``usr/usrapp`` (or open the ``.pjx`` with SRS) and run it.

Every point is a joint move ``movej(l_j, flange, l_m)`` to a local ``joint`` variable
(VAL3 s7 and later, the CS9's s8: ``joint``; CS8 applications (s6) name a SCARA's type
``jointRs``) whose fields are set just before (``l_j.j1 = ...`` .. ``l_j.j4``: degrees,
joint 3 of the SCARA in mm): no inverse kinematics between the plan and the arm. VAL3
queues moves ahead of the arm: ``waitEndMove()`` after every ``movej`` waits for the arm to
stand on the point (and ``l_m.blend = off`` keeps via points from being rounded off), so
the pen output and the waits follow the arrival. The motion descriptor ``l_m`` (local
``mdesc``) takes ``speed_percent`` (``vel``) and ``accel_percent`` (``accel``, ``decel``).
The pen output is ``doPen = true`` / ``false``; without ``pen_signal`` the writer refuses.
``delay(s)`` settles and dwells, ``putln`` prints progress, ``motor_off`` becomes
``disablePower()``. The moves name the predefined tool ``flange`` (a joint move does not go
through a tool). The application and every name in it are checked against VAL3's rules
(:mod:`vision_cal.program.rules`: a letter, then letters, digits or ``_``, at most 15; no
keyword, type, instruction, or name the application itself uses).
"""

from __future__ import annotations

from vision_cal import __version__
from vision_cal.errors import VisionCalError
from vision_cal.program.rules import RULES, check_pen_signal, check_program_name, plain
from vision_cal.program.steps import Move, Pen, Say, Wait, header_lines, program_steps, safe_text

J_FMT = "{:.4f}"
Z_FMT = "{:.3f}"
BANNED = '"<>&]\\'   # nothing that ends a VAL3 string, the CDATA section or the XML
VERSION = "s7.3.1"   # the project's VAL3 version (s7 and s8 controllers load it)
TOOL = "tPen"
LOCALS = ("l_j", "l_m")
PROGRAMS = ("start", "stop")
IO_BOARD = "BasicIO-1"
XSI = 'xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"'
NS_PROGRAM = 'xmlns="http://www.staubli.com/robotics/VAL3/Program/2"'


def check(robot, name: str | None = None) -> None:
    """Refuse what VAL3 cannot express: a pen output without its ``dio``'s name, a name
    VAL3 cannot take or the application already uses; with ``name`` (the output file's
    stem), an application name VAL3 cannot take."""
    prog = robot.program
    if prog.pen_output_bit is not None and prog.pen_signal is None:
        raise VisionCalError("missing: VAL3 sets an output through a dio variable; give its "
                             f"name (the pen's output, bit {prog.pen_output_bit}) as "
                             "program.pen_signal", file=str(robot.path),
                             field="program.pen_signal")
    own = (*PROGRAMS, *LOCALS, TOOL)
    if name is not None:
        check_program_name("val3", name, taken=own)
    check_pen_signal("val3", robot, taken=own if name is None else (*own, name))


def _code(points, robot, title: str, tool_mm) -> list[str]:
    """``start()``'s code lines, ``begin`` .. ``end``."""
    prog = robot.program
    note = (f"The calibrated tool is {TOOL} (x {tool_mm[0]:.4f} mm, y {tool_mm[1]:.4f} mm in "
            "the flange frame, in the application's data); the joint moves name flange and "
            "do not use it." if tool_mm is not None
            else "No calibrated tool: the moves name flange.")
    head = header_lines(points, robot, title=title, version=__version__,
                        joints="movej to joint values: j1, j2, j4 deg, j3 mm", tool=note)
    code = ["begin"] + [f"  // {safe_text(h, banned=BANNED)}" for h in head]
    code += [f"  l_m.vel = {plain(prog.speed_percent)}",
             f"  l_m.accel = {plain(prog.accel_percent[0])}",
             f"  l_m.decel = {plain(prog.accel_percent[1])}", "  l_m.blend = off"]
    for s in program_steps(points, robot):
        if isinstance(s, Move):
            q = s.q
            code += [f"  // {safe_text(s.note, banned=BANNED)}",
                     f"  l_j.j1 = {J_FMT.format(q[0])}", f"  l_j.j2 = {J_FMT.format(q[1])}",
                     f"  l_j.j3 = {Z_FMT.format(q[2])}", f"  l_j.j4 = {J_FMT.format(q[3])}",
                     "  movej(l_j, flange, l_m)", "  waitEndMove()"]
        elif isinstance(s, Wait):
            code.append(f"  delay({plain(s.seconds)})")
        elif isinstance(s, Pen):
            code.append(f"  {prog.pen_signal} = {'true' if s.down else 'false'}"
                        f"  // {safe_text(s.note, banned=BANNED)}")
        elif isinstance(s, Say):
            text = safe_text(s.text, banned=BANNED + "/", chars=RULES["val3"].string_max)
            code.append(f"  putln(\"{text}\")")
    if prog.motor_off:
        code.append("  disablePower()")
    return code + ["end"]


def _program(name: str, code: list[str], locals_: bool) -> str:
    """One ``.pgx`` file: the program ``name`` with ``code`` (and the motion locals)."""
    loc = ["    <Locals>",
           f'      <Local name="{LOCALS[0]}" type="joint" xsi:type="array" size="1" />',
           f'      <Local name="{LOCALS[1]}" type="mdesc" xsi:type="array" size="1" />',
           "    </Locals>"] if locals_ else []
    return "\n".join([
        '<?xml version="1.0" encoding="utf-8"?>',
        f"<Programs {XSI} {NS_PROGRAM}>",
        f'  <Program name="{name}">', *loc,
        "    <Code><![CDATA[" + "\n".join(code) + "]]></Code>",
        "  </Program>",
        "</Programs>", ""])


def _data(robot, tool_mm) -> str:
    """The ``.dtx``: the pen's ``dio`` and the calibrated tool, when there are."""
    prog = robot.program
    datas = []
    if prog.pen_output_bit is not None:
        datas += [f'    <Data name="{prog.pen_signal}" access="public" xsi:type="array" '
                  'type="dio" size="1">',
                  f'      <Value key="0" link="{IO_BOARD}\\%Q{prog.pen_output_bit}" />',
                  "    </Data>"]
    if tool_mm is not None:
        datas += [f'    <Data name="{TOOL}" access="public" xsi:type="array" type="tool" '
                  'size="1">',
                  f'      <Value key="0" x="{tool_mm[0]:.4f}" y="{tool_mm[1]:.4f}" z="0" '
                  'rx="0" ry="0" rz="0" fatherId="flange[0]" />',
                  "    </Data>"]
    return "\n".join([
        '<?xml version="1.0" encoding="utf-8"?>',
        f'<Database {XSI} xmlns="http://www.staubli.com/robotics/VAL3/Data/2">',
        "  <Datas>", *datas, "  </Datas>",
        "</Database>", ""])


def _project(name: str) -> str:
    return "\n".join([
        '<?xml version="1.0" encoding="utf-8"?>',
        '<Project xmlns="http://www.staubli.com/robotics/VAL3/Project/3">',
        f'  <Parameters version="{VERSION}" stackSize="5000" millimeterUnit="true" />',
        "  <Programs>", *[f'    <Program file="{p}.pgx" />' for p in PROGRAMS],
        "  </Programs>",
        "  <Database>", f'    <Data file="{name}.dtx" />', "  </Database>",
        "  <Libraries />",
        "</Project>", ""])


def val3_application(points, robot, *, title: str, tool_mm=None,
                     name: str = "program") -> dict[str, str]:
    """The application ``name``: file name (inside its folder) -> text."""
    check(robot, name)
    stop = ["begin", "  // the application stops: queued moves dropped, the pen up",
            "  resetMotion()"]
    if robot.program.pen_output_bit is not None:
        stop.append(f"  {robot.program.pen_signal} = false")
    return {f"{name}.pjx": _project(name), f"{name}.dtx": _data(robot, tool_mm),
            "start.pgx": _program("start", _code(points, robot, title, tool_mm), True),
            "stop.pgx": _program("stop", stop + ["end"], False)}
