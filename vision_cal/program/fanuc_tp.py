"""``--program tp``: a Fanuc TP program in its ASCII form (``.ls``, for an SR-series SCARA
on an R-30iB; load it with the controller's ASCII upload or compile it with ``maketp``).

Every point is ``J P[n] s% FINE`` to a position stored in joint representation in the
``/POS`` section (``J1=... deg, J2=... deg, J3=... mm, J4=... deg``, 3 decimals as the
controller writes them): no inverse kinematics between the plan and the arm. ``FINE``
makes each point a stop point: the next line runs once the arm stands on it, so the pen
output and the waits follow the arrival and no ``CNT`` corner rounds off a via point.
The pen output is ``DO[n]=ON`` / ``DO[n]=OFF`` (``DO[0]`` does not exist: refused);
``WAIT x.xx(sec)`` settles and dwells; the joint speed is ``speed_percent`` %. Remarks
(``!``) are cut to 32 characters. ``UFRAME_NUM=0`` and ``UTOOL_NUM=1`` are selected and
recorded with every point (a joint position does not depend on them). The calibrated tool
(``tool_mm``) is written as a remark only (``!UTOOL[1] x ... y ...``, mm, 3 decimals): set
it as UTOOL[1] on the pendant (a TP program can only set a tool frame through a position
register, which would overwrite the user's data). ``motor_off``, ``power`` and
``accel_percent`` have no TP counterpart and are ignored. Syntax after Fanuc's TP ASCII
(``.ls``) format and RoboDK's Fanuc R-30iA post-processor; see docs/controllers.md.
"""

from __future__ import annotations

import textwrap

from vision_cal import __version__
from vision_cal.errors import VisionCalError
from vision_cal.program.steps import Move, Pen, Say, Wait, header_lines, program_steps, safe_text

REMARK_CHARS = 32


def _remark(text: str) -> str:
    return "!" + safe_text(text, banned='";')[:REMARK_CHARS]


def _pos(n: int, q) -> list[str]:
    return [f"P[{n}]{{", "   GP1:", "\tUF : 0, UT : 1,",
            f"\tJ1= {q[0]:10.3f} deg,\tJ2= {q[1]:10.3f} deg,\tJ3= {q[2]:10.3f}  mm,",
            f"\tJ4= {q[3]:10.3f} deg", "};"]


def check(robot) -> None:
    """Refuse what TP cannot express: ``DO[0]`` (Fanuc's outputs count from 1)."""
    bit = robot.program.pen_output_bit
    if bit is not None and bit < 1:
        raise VisionCalError(f"a Fanuc digital output is DO[1] and up, got {bit}",
                             file=str(robot.path), field="program.pen_output_bit")


def tp_program(points, robot, *, title: str, tool_mm=None) -> str:
    check(robot)
    prog = robot.program
    bit = prog.pen_output_bit
    head = header_lines(points, robot, title=title, version=__version__,
                        joints="P[n] in joint representation: J1, J2, J4 deg, J3 mm",
                        tool=("The calibrated tool (x, y mm, next line): set it as UTOOL[1] on "
                              "the pendant; the joint moves do not use it."
                              if tool_mm is not None else "No calibrated tool."))
    # the title, then the rest as one paragraph in remarks of 32 characters
    body = [_remark(chunk) for para in (head[:1], head[1:])
            for chunk in textwrap.wrap(safe_text(" ".join(para), banned='";'), REMARK_CHARS)]
    if tool_mm is not None:
        body.append(_remark(f"UTOOL[1] x {tool_mm[0]:.3f} y {tool_mm[1]:.3f}"))
    body += ["UFRAME_NUM=0", "UTOOL_NUM=1"]
    pos, n = [], 0
    speed = max(1, min(100, round(prog.speed_percent)))
    for s in program_steps(points, robot):
        if isinstance(s, Move):
            n += 1
            body.append(f"J P[{n}] {speed}% FINE")
            pos += _pos(n, s.q)
        elif isinstance(s, Wait):
            body.append(f"WAIT {s.seconds:6.2f}(sec)")
        elif isinstance(s, Pen):
            body.append(f"DO[{bit}]={'ON' if s.down else 'OFF'}")
        elif isinstance(s, Say):
            body.append(_remark(s.text))
    mn = [f"{i:4d}:{'' if line.startswith('J ') else '  '}{line} ;"
          for i, line in enumerate(body, 1)]
    attr = ["/PROG  VISIONCAL", "/ATTR", "OWNER\t\t= MNEDITOR;",
            "COMMENT\t\t= \"vision-cal\";", "PROG_SIZE\t= 0;",
            "CREATE\t\t= DATE 00-01-01  TIME 00:00:00;",
            "MODIFIED\t= DATE 00-01-01  TIME 00:00:00;", "FILE_NAME\t= ;", "VERSION\t\t= 0;",
            f"LINE_COUNT\t= {len(body)};", "MEMORY_SIZE\t= 0;", "PROTECT\t\t= READ_WRITE;",
            "TCD:  STACK_SIZE\t= 0,", "      TASK_PRIORITY\t= 50,", "      TIME_SLICE\t= 0,",
            "      BUSY_LAMP_OFF\t= 0,", "      ABORT_REQUEST\t= 0,",
            "      PAUSE_REQUEST\t= 0;", "DEFAULT_GROUP\t= 1,*,*,*,*;",
            "CONTROL_CODE\t= 00000000 00000000;", "/MN"]
    return "\n".join(attr + mn + ["/POS"] + pos + ["/END"]) + "\n"
