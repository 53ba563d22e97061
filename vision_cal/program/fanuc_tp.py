"""``--program tp``: a Fanuc TP program in its ASCII form (``.ls``, for an SR-series SCARA
on an R-30iB; load it with the controller's ASCII upload or compile it with ``maketp``).

Every point is ``J P[n] s% FINE`` to a position stored in joint representation in the
``/POS`` section (``J1=... deg, J2=... deg, J3=... mm, J4=... deg``, 3 decimals as the
controller writes them): no inverse kinematics between the plan and the arm. ``FINE``
makes each point a stop point: the next line runs once the arm stands on it, so the pen
output and the waits follow the arrival and no ``CNT`` corner rounds off a via point.
The pen output is ``DO[n]=ON`` / ``DO[n]=OFF`` (``DO[0]`` does not exist: refused);
``WAIT x.xx(sec)`` settles and dwells; the joint speed is ``speed_percent`` %. Remarks
(``!``) are cut to 32 characters. ``UFRAME_NUM=0`` and ``UTOOL_NUM=n`` (n: the robot
file's ``program.tool_number``, else 1) are selected and recorded with every point (a joint
position does not depend on them). The calibrated tool (``tool_mm``) is written as a remark
only (``!UTOOL[n] x ... y ...``, mm, 3 decimals): set it as UTOOL[n] on the pendant (a TP
program can only set a tool frame through a position register, which would overwrite the
user's data). The joint speed is a whole percent: a fraction is rounded with a warning.
``motor_off``, ``power`` and ``accel_percent`` have no TP counterpart and are ignored.

The program is named after its file (``plan.ls``: ``/PROG  PLAN``): a letter, then
letters, digits or ``_``, at most 10 characters (RoboDK's Fanuc posts cut names there). A
program holds at most 9999 lines (the line numbers' four digits, where RoboDK's Fanuc post
splits): a longer plan is refused, naming how many marks one program holds. Syntax after
Fanuc's TP ASCII (``.ls``) format and RoboDK's Fanuc R-30iA post-processor; see
docs/controllers.md.
"""

from __future__ import annotations

import textwrap

from vision_cal import __version__
from vision_cal.errors import VisionCalError
from vision_cal.program.rules import RULES, check_program_name, check_tool_number
from vision_cal.program.steps import (Move, Pen, Say, Wait, header_lines, program_steps,
                                      safe_text, whole_percent)

REMARK_CHARS = RULES["tp"].string_max
TOOLS = (1, 10)    # UTOOL[1] .. UTOOL[10]


def _remark(text: str) -> str:
    return "!" + safe_text(text, banned='";')[:REMARK_CHARS]


def _pos(n: int, q, tool: int = 1) -> list[str]:
    return [f"P[{n}]{{", "   GP1:", f"\tUF : 0, UT : {tool},",
            f"\tJ1= {q[0]:10.3f} deg,\tJ2= {q[1]:10.3f} deg,\tJ3= {q[2]:10.3f}  mm,",
            f"\tJ4= {q[3]:10.3f} deg", "};"]


def check(robot, name: str | None = None) -> None:
    """Refuse what TP cannot express: ``DO[0]`` (Fanuc's outputs count from 1), a tool
    number beyond UTOOL[10]; with ``name`` (the output file's stem), a program name TP
    cannot take."""
    bit = robot.program.pen_output_bit
    if bit is not None and bit < 1:
        raise VisionCalError(f"a Fanuc digital output is DO[1] and up, got {bit}",
                             file=str(robot.path), field="program.pen_output_bit")
    check_tool_number(robot, TOOLS, "a Fanuc tool frame is UTOOL[n], n")
    if name is not None:
        check_program_name("tp", name)


def _check_lines(body: list[str], start: int, n_marks: int) -> None:
    """A program within TP's line limit, or one line saying how many marks fit (``start``:
    the lines before the first move)."""
    limit = RULES["tp"].lines_max
    if len(body) > limit:
        fit = max(0, int(n_marks * (limit - start) / (len(body) - start)) - 1)
        raise VisionCalError(f"a Fanuc TP program holds at most {limit} lines; these "
                             f"{n_marks} marks need {len(body)}: write at most {fit} marks "
                             "per program (split the targets into several plans)",
                             field="--program")


def tp_program(points, robot, *, title: str, tool_mm=None, name: str = "program") -> str:
    check(robot, name)
    prog = robot.program
    bit = prog.pen_output_bit
    tool = prog.tool_number or 1
    head = header_lines(points, robot, title=title, version=__version__,
                        joints="P[n] in joint representation: J1, J2, J4 deg, J3 mm",
                        tool=(f"The calibrated tool (x, y mm, next line): set it as UTOOL[{tool}] "
                              "on the pendant; the joint moves do not use it."
                              if tool_mm is not None else "No calibrated tool."))
    # the title, then the rest as one paragraph in remarks of 32 characters
    body = [_remark(chunk) for para in (head[:1], head[1:])
            for chunk in textwrap.wrap(safe_text(" ".join(para), banned='";'), REMARK_CHARS)]
    if tool_mm is not None:
        body.append(_remark(f"UTOOL[{tool}] x {tool_mm[0]:.3f} y {tool_mm[1]:.3f}"))
    body += ["UFRAME_NUM=0", f"UTOOL_NUM={tool}"]
    pos, n, start = [], 0, len(body)
    speed = whole_percent(prog.speed_percent, robot=robot, field="program.speed_percent",
                          language="a TP joint speed")
    for s in program_steps(points, robot):
        if isinstance(s, Move):
            n += 1
            body.append(f"J P[{n}] {speed}% FINE")
            pos += _pos(n, s.q, tool)
        elif isinstance(s, Wait):
            body.append(f"WAIT {s.seconds:6.2f}(sec)")
        elif isinstance(s, Pen):
            body.append(f"DO[{bit}]={'ON' if s.down else 'OFF'}")
        elif isinstance(s, Say):   # a long id: the message over two remarks
            body += [_remark(c) for c in textwrap.wrap(safe_text(s.text, banned='";'),
                                                       REMARK_CHARS)]
    _check_lines(body, start, sum(1 for p in points if p.kind == "mark"))
    mn = [f"{i:4d}:{'' if line.startswith('J ') else '  '}{line} ;"
          for i, line in enumerate(body, 1)]
    attr = [f"/PROG  {name.upper()}", "/ATTR", "OWNER\t\t= MNEDITOR;",
            "COMMENT\t\t= \"vision-cal\";", "PROG_SIZE\t= 0;",
            "CREATE\t\t= DATE 00-01-01  TIME 00:00:00;",
            "MODIFIED\t= DATE 00-01-01  TIME 00:00:00;", "FILE_NAME\t= ;", "VERSION\t\t= 0;",
            f"LINE_COUNT\t= {len(body)};", "MEMORY_SIZE\t= 0;", "PROTECT\t\t= READ_WRITE;",
            "TCD:  STACK_SIZE\t= 0,", "      TASK_PRIORITY\t= 50,", "      TIME_SLICE\t= 0,",
            "      BUSY_LAMP_OFF\t= 0,", "      ABORT_REQUEST\t= 0,",
            "      PAUSE_REQUEST\t= 0;", "DEFAULT_GROUP\t= 1,*,*,*,*;",
            "CONTROL_CODE\t= 00000000 00000000;", "/MN"]
    return "\n".join(attr + mn + ["/POS"] + pos + ["/END"]) + "\n"
