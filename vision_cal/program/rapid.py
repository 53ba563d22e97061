"""``--program rapid``: an ABB RAPID module (``.mod``) for an IRB 910SC (IRC5 / OmniCore).

Every point is an absolute joint move ``MoveAbsJ [[j1, j2, j3, j4, 0, 0], [9E9, ...]]
\\NoEOffs, v, fine, tool;`` (jointtarget: ``robax`` in degrees, joint 3 of the SCARA in mm;
``rax_5``/``rax_6`` do not exist on a 4-axis arm and are written 0; no external axes:
9E9). ``fine``: every point is a stop point, so the program waits for the arm to stand on
it before the next instruction (the pen I/O and waits come after the arm arrived, and no
corner zone rounds off a via point). ``WaitTime \\InPos`` settles and dwells.

The module and its routine are named after the output file (``plan.mod``: ``MODULE
MOD_plan``, ``PROC plan()``, as RoboDK's ABB post-processor names them), so two plans load
into one task side by side; the name is checked against RAPID's rules and reserved words
(:mod:`vision_cal.program.rules`).

The pen output (``pen_output_bit`` in the robot file) needs its signal's name in RAPID:
``program.pen_signal`` (``SetDO doPen, 1``); without it, or with a name RAPID reserves or
the module uses, the writer refuses. The calibrated tool (``tool_mm``) is written as the
module's own ``LOCAL PERS tooldata tVisionCal`` (x, y in the flange frame, no rotation;
mass 0.1 kg, a placeholder: no tool of the controller, nor of another module, is
overwritten) and named in every ``MoveAbsJ``; a joint move does not go through it (it only
sets the TCP speed). ``speed_percent`` becomes ``VelSet``, ``accel_percent`` ``AccSet``
(below 20 % RAPID uses 20 %: written 20 with a warning). RAPID has no Motor Off
instruction: ``motor_off`` is ignored (a comment says so). Messages (``TPWrite``) keep to
RAPID's 80 characters. Syntax after ABB's RAPID reference (MoveAbsJ, jointtarget, tooldata,
SetDO, WaitTime, VelSet, AccSet, TPWrite); see docs/controllers.md.
"""

from __future__ import annotations

import logging

from vision_cal import __version__
from vision_cal.errors import VisionCalError
from vision_cal.program.rules import RULES, check_pen_signal, check_program_name, plain
from vision_cal.program.steps import Move, Pen, Say, Wait, header_lines, program_steps, safe_text

log = logging.getLogger(__name__)

J_FMT = "{:.4f}"
Z_FMT = "{:.3f}"
TOOL = "tVisionCal"
SPEED = "v500"   # speeddata of every move: the TCP speed VelSet scales
ACC_MIN = 20     # AccSet: "Input value < 20% gives 20% of maximum acceleration"


def names(name: str) -> tuple[str, str]:
    """(module, routine) of a program written to ``name.mod``."""
    return f"MOD_{name}", name


def jointtarget(q) -> str:
    return (f"[[{J_FMT.format(q[0])},{J_FMT.format(q[1])},{Z_FMT.format(q[2])},"
            f"{J_FMT.format(q[3])},0,0],[9E9,9E9,9E9,9E9,9E9,9E9]]")


def check(robot, name: str | None = None) -> None:
    """Refuse what RAPID cannot express: a pen output without its signal's name, a signal
    name RAPID reserves or the module uses; with ``name`` (the output file's stem), a
    module or routine name RAPID cannot take."""
    prog = robot.program
    if prog.pen_output_bit is not None and prog.pen_signal is None:
        raise VisionCalError("missing: RAPID sets an output by its signal's name; give the "
                             f"pen's output (bit {prog.pen_output_bit}) as program.pen_signal",
                             file=str(robot.path), field="program.pen_signal")
    taken = (TOOL, *names(name)) if name is not None else (TOOL,)
    if name is not None:
        for n in names(name):
            check_program_name("rapid", n, taken=(TOOL,))
    check_pen_signal("rapid", robot, taken=taken)


def _accset(robot) -> str:
    """``AccSet acc, 100;``: the smaller of the two percentages, 20 at least (a warning
    when raised)."""
    acc = min(robot.program.accel_percent)
    if acc < ACC_MIN:
        log.warning("%s: program.accel_percent: %s %% is written as AccSet %d (RAPID takes "
                    "less than %d %% as %d %%)", robot.path, plain(acc), ACC_MIN, ACC_MIN,
                    ACC_MIN)
        acc = ACC_MIN
    return f"AccSet {plain(acc)}, 100;"


def rapid_program(points, robot, *, title: str, tool_mm=None, name: str = "program") -> str:
    check(robot, name)
    module, routine = names(name)
    prog = robot.program
    tool = "tool0" if tool_mm is None else TOOL
    head = header_lines(points, robot, title=title, version=__version__,
                        joints="MoveAbsJ jointtargets: j1, j2, j4 deg, j3 mm",
                        tool=("The calibrated tool is tVisionCal (x, y in the flange frame); "
                              "the joint moves do not use it." if tool_mm is not None else
                              "No calibrated tool: the moves name tool0."))
    lines = [f"MODULE {module}"]
    lines += [f"    ! {safe_text(h)}" for h in head]
    if tool_mm is not None:
        lines.append(f"    LOCAL PERS tooldata {TOOL} := [TRUE,[[{tool_mm[0]:.4f},"
                     f"{tool_mm[1]:.4f},0],[1,0,0,0]],[0.1,[0,0,1],[1,0,0,0],0,0,0]];")
    lines += ["", f"    PROC {routine}()",
              f"        VelSet {plain(prog.speed_percent)}, 5000;",
              f"        {_accset(robot)}"]
    for s in program_steps(points, robot):
        if isinstance(s, Move):
            lines.append(f"        MoveAbsJ {jointtarget(s.q)}\\NoEOffs, {SPEED}, fine, {tool};"
                         f"  ! {safe_text(s.note)}")
        elif isinstance(s, Wait):
            lines.append(f"        WaitTime \\InPos, {plain(s.seconds)};")
        elif isinstance(s, Pen):
            lines.append(f"        SetDO {prog.pen_signal}, {1 if s.down else 0};"
                         f"  ! {safe_text(s.note)}")
        elif isinstance(s, Say):
            text = safe_text(s.text, banned='"\\!', chars=RULES["rapid"].string_max)
            lines.append(f"        TPWrite \"{text}\";")
    if prog.motor_off:
        lines.append("        ! motor_off: RAPID cannot switch the motors off; do it on the "
                     "FlexPendant")
    lines += ["    ENDPROC", "ENDMODULE"]
    return "\n".join(lines) + "\n"
