"""Robot programs for every controller (SPEL+, RAPID, VAL3, eV+, PacScript, Fanuc TP): each
read back by the strict reader of its language (tests/program/checkers.py: any statement,
name, string or line count it does not take fails the test), and the joints it drives
compared with the plan's: home first and last, each mark's via point just before the mark,
the pen down on the mark's planned joints, to the written precision.
"""

import argparse
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from vision_cal.commands import design as design_cmd
from vision_cal.commands import plan as plan_cmd
from vision_cal.dataset.robot import load_robot_file
from vision_cal.errors import VisionCalError
from vision_cal.plan.calibration_plan import PlannedMark
from vision_cal.program import KINDS, WRITERS, program_path, program_points, write_program

from tests.program.checkers import READERS, read_program

ROBOT = Path(__file__).resolve().parents[2] / "fixtures" / "robot_sm5.yaml"
# written precision: joints 1, 2, 4 to 4 decimals (TP: 3), joint 3 to 3
TOL = {"spel": (0.5e-4, 0.5e-3), "rapid": (0.5e-4, 0.5e-3), "val3": (0.5e-4, 0.5e-3),
       "evplus": (0.5e-4, 0.5e-3), "pacscript": (0.5e-4, 0.5e-3), "tp": (0.5e-3, 0.5e-3)}
TOOL = (12.34567, -3.21)


# ------------------------------------------------------------------------------ the plan

def robot_with(**program):
    r = load_robot_file(ROBOT)
    return dataclasses.replace(r, program=dataclasses.replace(r.program, **program))


def plan(seed=7, n=6):
    """Marks at random joints (more decimals than any dialect writes), their via points
    3 deg before on the approach side (the first mark: two, 6 and 3 deg before); joint 4
    turned on half of them."""
    rng = np.random.default_rng(seed)
    marks, joint4 = [], {}
    for i in range(n):
        q = (rng.uniform(-120, 120), rng.uniform(-130, 130))
        s = tuple(int(v) for v in rng.choice([-1, 1], 2))
        via = ((q[0] - 3 * s[0], q[1] - 3 * s[1]),)
        if i == 0:   # two via points: the farther first
            via = ((q[0] - 6 * s[0], q[1] - 6 * s[1]), *via)
        marks.append(PlannedMark(f"m{i}", q, "target", s, via))
        if i % 2:
            q4 = rng.uniform(-90, 90)
            joint4[f"m{i}"] = (q4, q4 - 3.0)
    return marks, joint4


def drawn(ops, up, down, by_output):
    """(joints where the pen went down, the move before each mark's arrival, all moves)."""
    moves, pen_at, before = [], [], []
    last = None
    for op, arg in ops:
        if op == "move":
            if not by_output and abs(arg[2] - down) < 1e-6:
                pen_at.append(arg)
                before.append(moves[-2])   # moves[-1] is the mark at pen-up height
            moves.append(arg)
            last = arg
        elif op == "pen" and arg:
            pen_at.append(last)
            before.append(moves[-2])
    return pen_at, before, moves


@pytest.mark.parametrize("kind", sorted(READERS))
@pytest.mark.parametrize("by_output", [False, True])
def test_joints_read_back_equal_the_plan(tmp_path, kind, by_output):
    robot = robot_with(pen_output_bit=9 if by_output else None,
                       pen_signal="doPen" if by_output else None)
    up, down = robot.pen_up_mm, robot.pen_down_mm
    marks, joint4 = plan()
    points = program_points(marks, home_deg=(5.0, -7.0), joint4=joint4)
    path = write_program(kind, program_path(kind, tmp_path / "program"), points, robot,
                         title="test", tool_mm=TOOL)
    ops, tool = read_program(kind, path)
    tol_deg, tol_mm = TOL[kind]
    tol = np.array([tol_deg, tol_deg, tol_mm, tol_deg]) + 1e-9
    pen_at, before, moves = drawn(ops, up, down, by_output)

    assert len(pen_at) == len(marks)
    for m, q, b in zip(marks, pen_at, before):
        q4, q4_via = joint4.get(m.id, (robot.j4_deg, robot.j4_deg))
        z = up if by_output else down
        assert np.all(np.abs(np.subtract(q, (*m.joints_deg, z, q4))) <= tol), (m.id, q)
        assert np.all(np.abs(np.subtract(b, (*m.via_deg[-1], up, q4_via))) <= tol), (m.id, b)
    for q in (moves[0], moves[-1]):
        assert np.all(np.abs(np.subtract(q, (5.0, -7.0, up, robot.j4_deg))) <= tol)
    # pen down only on a mark, up before the arm moves on; settle before, dwell while down
    pens = [a for op, a in ops if op == "pen"]
    assert pens == ([True, False] * len(marks) if by_output else [])
    assert [a for op, a in ops if op == "wait"] == [robot.program.settle_s,
                                                    robot.program.pen_dwell_s] * len(marks)
    assert tool is not None and np.allclose(tool, TOOL, rtol=0, atol=tol_mm + 1e-9)


@pytest.mark.parametrize("kind", sorted(READERS))
def test_safe_height_travel_keeps_the_last_move_onto_each_mark(tmp_path, kind):
    robot = robot_with(safe_z_mm=-2.0)
    marks, joint4 = plan(seed=11, n=3)
    points = program_points(marks, joint4=joint4)
    path = write_program(kind, program_path(kind, tmp_path / "program"), points, robot,
                         title="t")
    ops, tool = read_program(kind, path)
    moves = [a for op, a in ops if op == "move"]
    assert tool is None
    # every travel rises to the safe height where the arm is, moves there, comes down
    rises = [i for i, q in enumerate(moves) if abs(q[2] + 2.0) < 1e-6]
    assert len(rises) == 2 * (len(marks) + 2) - 1   # the start has no known place to rise
    pen_at, before, _ = drawn(ops, robot.pen_up_mm, robot.pen_down_mm, False)
    for m, b in zip(marks, before):
        assert abs(b[0] - m.via_deg[-1][0]) < 1e-3 and abs(b[2] - robot.pen_up_mm) < 1e-6


@pytest.mark.parametrize("kind, program, field", [
    ("rapid", {"pen_output_bit": 9}, "program.pen_signal"),
    ("val3", {"pen_output_bit": 9}, "program.pen_signal"),
    ("evplus", {"pen_output_bit": 0}, "program.pen_output_bit"),
    ("tp", {"pen_output_bit": 0}, "program.pen_output_bit"),
])
def test_refuses_what_the_dialect_cannot_express(tmp_path, kind, program, field):
    robot = robot_with(**program)
    marks, _ = plan(n=2)
    target = program_path(kind, tmp_path / "program")
    with pytest.raises(VisionCalError) as e:
        write_program(kind, target, program_points(marks), robot, title="t")
    assert e.value.field == field and e.value.file == str(robot.path)
    assert not target.exists()


@pytest.mark.parametrize("kind, program", [("rapid", {"pen_output_bit": 9}),
                                           ("val3", {"pen_output_bit": 9}),
                                           ("evplus", {"pen_output_bit": 0}),
                                           ("tp", {"pen_output_bit": 0})])
def test_each_writer_refuses_on_its_own(kind, program):
    """Called directly (not through write_program), a writer still refuses."""
    with pytest.raises(VisionCalError):
        WRITERS[kind][0](program_points(plan(n=1)[0]), robot_with(**program), title="t")


def test_val3_application_is_named_after_its_file(tmp_path):
    marks, _ = plan(n=1)
    path = write_program("val3", program_path("val3", tmp_path / "draw_1"),
                         program_points(marks), robot_with(), title="t")
    assert path == tmp_path / "draw_1" / "draw_1.pjx"
    read_program("val3", path)
    target = program_path("val3", tmp_path / "1-draw")
    with pytest.raises(VisionCalError) as e:
        write_program("val3", target, program_points(marks), robot_with(), title="t")
    assert e.value.field == "--program" and not target.parent.exists()


def test_pen_signal_is_read_and_checked(tmp_path):
    text = ROBOT.read_text()
    good = tmp_path / "good.yaml"
    good.write_text(text.replace("  pen_dwell_s: 0.2", "  pen_dwell_s: 0.2\n  pen_signal: doPen"))
    assert load_robot_file(good).program.pen_signal == "doPen"
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("  pen_dwell_s: 0.2", "  pen_dwell_s: 0.2\n  pen_signal: 9pen"))
    with pytest.raises(VisionCalError) as e:
        load_robot_file(bad)
    assert e.value.field == "program.pen_signal"


def test_every_kind_has_a_file_beside_the_plan(tmp_path):
    paths = {program_path(k, tmp_path / "plan") for k in KINDS}
    assert len(paths) == len(KINDS)
    assert {"rapid", "val3", "evplus", "pacscript", "tp"} <= set(KINDS)


@pytest.mark.parametrize("kind", sorted(READERS))
def test_a_mark_id_cannot_break_the_program(tmp_path, kind):
    """Ids come from the user's targets.csv: quotes, comment and statement characters, a
    line break, XML and non-ASCII text stay inside the message or the comment."""
    marks, _ = plan(n=2)
    marks = [dataclasses.replace(m, id=f'é{k}"b;c!d\'e//f\\g]]>h<&i\nj')
             for k, m in enumerate(marks)]
    robot = robot_with(pen_output_bit=9, pen_signal="doPen")
    path = write_program(kind, program_path(kind, tmp_path / "program"), program_points(marks),
                         robot, title='title "with" ; quotes', tool_mm=TOOL)
    ops, _ = read_program(kind, path)
    assert sum(1 for op, a in ops if op == "pen" and a) == 2
    assert len([1 for op, _ in ops if op == "move"]) == 2 + sum(len(m.via_deg) + 1 for m in marks)


def test_the_commands_offer_every_kind():
    """`plan` and `design` list the kinds themselves (no import of the writers at startup):
    a new dialect cannot be left out of either."""
    for module, extra in ((plan_cmd, set()), (design_cmd, {"none"})):
        p = argparse.ArgumentParser()
        module.add_arguments(p)
        (action,) = [a for a in p._actions if "--program" in a.option_strings]
        assert set(action.choices) == set(KINDS) | extra
