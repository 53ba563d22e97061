"""`vision-cal plan --program rapid|val3|evplus|tp`: the program beside the plan drives
the plan's joints; a robot file the dialect cannot express is refused before anything is
written (exit 2, one line naming the robot file and its field)."""

from __future__ import annotations

import csv
import shutil

import pytest

from vision_cal.program import program_path

from tests.commands.test_trust import (ROOT, TARGETS, assert_one_line, calibration,  # noqa: F401
                                       cli, snapshot)
from tests.program.checkers import read_program

ROBOT = ROOT / "fixtures" / "robot_sm5.yaml"


@pytest.fixture()
def work(tmp_path, calibration):  # noqa: F811
    d = tmp_path / "w"
    d.mkdir()
    shutil.copy(calibration, d / "cal.json")
    shutil.copy(TARGETS, d / "targets.csv")
    shutil.copy(ROBOT, d / "robot.yaml")
    return d


@pytest.mark.parametrize("kind", ["rapid", "tp", "val3", "evplus"])
def test_plan_writes_the_program_of_the_plan_joints(work, capsys, kind):
    rc, _, err = cli(["plan", work / "cal.json", work / "targets.csv", "-o", work / "p.csv",
                      "--program", kind, "--robot", work / "robot.yaml", "--force", "-q"],
                     capsys)   # the paper's marks cover joint 1 -20..20 only (valid_for)
    assert rc == 3, err   # "far" is out of reach: planned in part
    ops, _ = read_program(kind, program_path(kind, work / "p"))
    with open(work / "p.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    down = -20.5   # the fixture's pen_down_mm: joint 3 lowers the pen
    pen = [q for op, q in ops if op == "move" and abs(q[2] - down) < 1e-9]
    assert len(pen) == len(rows) > 0
    tol = 0.5e-4 if kind == "rapid" else 0.5e-3
    for row, q in zip(rows, pen):
        assert abs(float(row["q1_deg"]) - q[0]) <= tol + 1e-9
        assert abs(float(row["q2_deg"]) - q[1]) <= tol + 1e-9


def test_plan_refuses_a_pen_output_rapid_cannot_name(work, capsys):
    robot = work / "robot.yaml"
    robot.write_text(robot.read_text().replace("  pen_dwell_s: 0.2",
                                               "  pen_dwell_s: 0.2\n  pen_output_bit: 9"))
    before = snapshot(work)
    rc, _, err = cli(["plan", work / "cal.json", work / "targets.csv", "-o", work / "p.csv",
                      "--program", "rapid", "--robot", robot, "--force", "-q"], capsys)
    assert rc == 2
    assert_one_line(err, robot, "program.pen_signal")
    assert snapshot(work) == before


def test_plan_refuses_a_travel_height_into_the_table(work, capsys):
    """`program.safe_z_mm: -100` with the pen at -10 / -20.5: exit 2, one line naming the
    robot file and the field, nothing written."""
    robot = work / "robot.yaml"
    robot.write_text(robot.read_text().replace("  pen_dwell_s: 0.2",
                                               "  pen_dwell_s: 0.2\n  safe_z_mm: -100"))
    before = snapshot(work)
    rc, _, err = cli(["plan", work / "cal.json", work / "targets.csv", "-o", work / "p.csv",
                      "--program", "rapid", "--robot", robot, "--force", "-q"], capsys)
    assert rc == 2
    assert_one_line(err, robot, "program.safe_z_mm")
    assert snapshot(work) == before


@pytest.mark.parametrize("kind, out", [("evplus", "2plan.csv"), ("val3", "start.csv"),
                                       ("rapid", "ENDIF.csv")])
def test_plan_refuses_a_program_name_the_language_cannot_take(work, capsys, kind, out):
    """The program is named after -o's file: a name the controller's language refuses is
    refused before the plan, its failed targets or the program are written."""
    before = snapshot(work)
    rc, _, err = cli(["plan", work / "cal.json", work / "targets.csv", "-o", work / out,
                      "--program", kind, "--robot", work / "robot.yaml", "--force", "-q"],
                     capsys)
    assert rc == 2
    assert_one_line(err, "--program")
    assert snapshot(work) == before
    assert not (work / out[:-4]).exists()   # no VAL3 application folder either
