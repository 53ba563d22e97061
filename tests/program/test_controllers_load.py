"""Every dialect as its controller loads it (issue 38): names from the output file checked
against the language's rules and reserved words, strings and programs within their limits,
no controller tool overwritten unasked, numbers without exponents, and no travel height
that drives the pen into the table. Each program is read back by its language's strict
reader (tests/program/checkers.py)."""

import dataclasses
import logging
from pathlib import Path

import numpy as np
import pytest

from vision_cal.dataset.robot import load_robot_file
from vision_cal.errors import VisionCalError
from vision_cal.plan.calibration_plan import PlannedMark
from vision_cal.program import program_path, program_points, write_program

from tests.program.checkers import READERS, read_program
from tests.program.test_dialects import ROBOT, TOOL, plan, robot_with

DOCS = Path(__file__).resolve().parents[2] / "docs" / "controllers.md"


def write(kind, folder, stem="program", robot=None, marks=None, **kw):
    marks = plan(n=2)[0] if marks is None else marks
    return write_program(kind, program_path(kind, Path(folder) / stem), program_points(marks),
                         robot or robot_with(), title="t", **kw)


def refused(kind, folder, stem="program", robot=None, **kw) -> VisionCalError:
    target = program_path(kind, Path(folder) / stem)
    with pytest.raises(VisionCalError) as e:
        write(kind, folder, stem, robot, **kw)
    folder = Path(folder)
    assert not target.exists(), "the program was written"
    assert not folder.exists() or not any(folder.iterdir()), "something was written"
    return e.value


# ------------------------------------------------------------------------------ VAL3

def test_val3_is_an_application_folder_the_controller_loads(tmp_path):
    robot = robot_with(pen_output_bit=9, pen_signal="doPen")
    path = write("val3", tmp_path, "draw", robot, tool_mm=TOOL)
    assert sorted(p.name for p in path.parent.iterdir()) == [
        "draw.dtx", "draw.pjx", "start.pgx", "stop.pgx"]
    ops, tool = read_program("val3", path)
    assert np.allclose(tool, TOOL, atol=0.5e-4)
    dtx = (path.parent / "draw.dtx").read_text()
    assert 'name="doPen"' in dtx and 'link="BasicIO-1\\%Q9"' in dtx
    assert [a for op, a in ops if op == "pen"] == [True, False, True, False]


@pytest.mark.parametrize("signal", ["doPenOfThePlotter", "l_m", "begin", "start", "flange",
                                    "tPen", "draw"])
def test_val3_refuses_a_pen_signal_it_cannot_name(tmp_path, signal):
    robot = robot_with(pen_output_bit=9, pen_signal=signal)
    e = refused("val3", tmp_path, "draw", robot)
    assert e.field == "program.pen_signal" and e.file == str(robot.path)


@pytest.mark.parametrize("stem", ["start", "stop", "l_j", "endFor", "a_long_plan_name_x"])
def test_val3_refuses_an_application_name_it_cannot_take(tmp_path, stem):
    assert refused("val3", tmp_path, stem).field == "--program"


def test_the_docs_name_a_cs8_scaras_joint_type_jointrs():
    text = DOCS.read_text()
    assert "jointRs" in text and "jointRx" not in text


# ------------------------------------------------------------------------------ eV+

@pytest.mark.parametrize("kind", sorted(READERS))
def test_messages_keep_within_the_languages_strings(tmp_path, kind):
    """A 300-character id: eV+'s TYPE gave 316 characters (the guide's limit is 128); every
    reader checks its language's limit, and the marks' numbers still tell them apart."""
    marks = [dataclasses.replace(m, id="x" * 300 + str(i)) for i, m in enumerate(plan(n=2)[0])]
    ops, _ = read_program(kind, write(kind, tmp_path, marks=marks))
    said = " ".join(a for op, a in ops if op == "say")
    assert "(1 of 2)" in said and "(2 of 2)" in said


def test_evplus_programs_are_named_after_their_files(tmp_path):
    a = write("evplus", tmp_path, "plan_a")
    b = write("evplus", tmp_path, "plan.b")
    assert a.read_text().startswith(".PROGRAM plan_a()\n")
    assert b.read_text().startswith(".PROGRAM plan.b()\n")
    read_program("evplus", b)


@pytest.mark.parametrize("stem", ["1plan", "type", "plan-a", "calibration_plan1"])
def test_evplus_refuses_a_program_name_it_cannot_take(tmp_path, stem):
    assert refused("evplus", tmp_path, stem).field == "--program"


# ------------------------------------------------------------------------------ Fanuc TP

def test_tp_program_is_named_after_its_file(tmp_path):
    path = write("tp", tmp_path, "cal_7")
    assert "/PROG  CAL_7\n" in path.read_text()
    read_program("tp", path)
    assert refused("tp", tmp_path / "x", "calibration").field == "--program"


def _grid(n):
    """n marks on a grid of joints (cheap: no model)."""
    q = [(-60 + 120 * (i % 40) / 40, -100 + 200 * (i // 40) / 40) for i in range(n)]
    return [PlannedMark(f"m{i}", p, "target", (1, 1), ((p[0] - 3, p[1] - 3),))
            for i, p in enumerate(q)]


def test_tp_refuses_more_lines_than_a_program_holds(tmp_path):
    path = write("tp", tmp_path / "a", marks=_grid(1400))   # 9,829 lines: loads
    read_program("tp", path)
    (tmp_path / "b").mkdir()
    e = refused("tp", tmp_path / "b", marks=_grid(1430))
    assert "at most 9999 lines" in str(e) and "1430 marks" in str(e)
    fit = int(str(e).split("write at most ")[1].split()[0])
    write("tp", tmp_path / "c", marks=_grid(fit))           # what it says fits, fits


def test_tp_speed_is_rounded_only_with_a_warning(tmp_path, caplog):
    with caplog.at_level(logging.WARNING):
        path = write("tp", tmp_path, robot=robot_with(speed_percent=12.5))
    assert " 12% FINE" in path.read_text()
    assert "program.speed_percent: 12.5 % is written as 12 %" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        write("tp", tmp_path / "x", robot=robot_with(speed_percent=12.0))
    assert caplog.text == ""


# ------------------------------------------------------------------------------ RAPID

@pytest.mark.parametrize("signal", ["ENDPROC", "main", "tool0", "MoveAbsJ", "tVisionCal",
                                    "plan", "MOD_plan"])
def test_rapid_refuses_a_pen_signal_it_cannot_name(tmp_path, signal):
    robot = robot_with(pen_output_bit=9, pen_signal=signal)
    e = refused("rapid", tmp_path, "plan", robot)
    assert e.field == "program.pen_signal" and e.file == str(robot.path)


def test_rapid_modules_are_named_after_their_files(tmp_path):
    a, b = write("rapid", tmp_path, "plan_a"), write("rapid", tmp_path, "plan_b")
    heads = [p.read_text().splitlines()[0] for p in (a, b)]
    assert heads == ["MODULE MOD_plan_a", "MODULE MOD_plan_b"]
    assert "    PROC plan_b()" in b.read_text().splitlines()
    read_program("rapid", b)
    for stem in ("ENDIF", "a" * 29, "2plan"):
        assert refused("rapid", tmp_path / stem, stem).field == "--program"


def test_rapid_acceleration_below_20_percent_is_raised_with_a_warning(tmp_path, caplog):
    with caplog.at_level(logging.WARNING):
        path = write("rapid", tmp_path, robot=robot_with(accel_percent=(10.0, 30.0)))
    assert "        AccSet 20, 100;" in path.read_text().splitlines()
    assert "program.accel_percent: 10 % is written as AccSet 20" in caplog.text


# ------------------------------------------------------------------------------ PacScript

@pytest.mark.parametrize("stem", ["1plan", "Sub", "Move", "p" * 65, "plan-a"])
def test_pacscript_refuses_a_program_name_it_cannot_take(tmp_path, stem):
    assert refused("pacscript", tmp_path, stem).field == "--program"


@pytest.mark.parametrize("kind, defines, number", [
    ("pacscript", "Tool {n}, P(", None), ("spel", "TLSet {n}, XY(", None),
    ("evplus", "TOOL TRANS(", None), ("pacscript", "Tool {n}, P(", 3),
    ("spel", "TLSet {n}, XY(", 7), ("evplus", "TOOL TRANS(", 2)])
def test_no_controller_tool_is_overwritten_unasked(tmp_path, kind, defines, number):
    path = write(kind, tmp_path, robot=robot_with(tool_number=number), tool_mm=TOOL)
    code = [ln.split("'")[0].split(";")[0].strip() for ln in path.read_text().splitlines()]
    written = [c for c in code if c.startswith(defines.format(n=number or 1)[:5])]
    if number is None:
        assert written == []
    else:
        assert written and written[0].startswith(defines.format(n=number))
    _, tool = read_program(kind, path)
    assert np.allclose(tool, TOOL, atol=0.5e-4)   # still written, as a comment


@pytest.mark.parametrize("kind, number", [("spel", 16), ("pacscript", 64), ("tp", 11)])
def test_a_tool_number_the_controller_has_not_is_refused(tmp_path, kind, number):
    e = refused(kind, tmp_path, robot=robot_with(tool_number=number), tool_mm=TOOL)
    assert e.field == "program.tool_number"


# ------------------------------------------------------------------------------ all

@pytest.mark.parametrize("kind", sorted(READERS))
def test_waits_are_written_without_exponents(tmp_path, kind):
    robot = robot_with(settle_s=5e-05, pen_dwell_s=1234567.0, pen_output_bit=9,
                       pen_signal="doPen")
    ops, _ = read_program(kind, write(kind, tmp_path, robot=robot))   # no exponent: reads
    waits = [a for op, a in ops if op == "wait"]
    assert waits[1] == 1234567.0
    assert waits[0] == pytest.approx(5e-05, abs=0.005)   # TP: 0.01 s, PacScript: 1 ms


def _robot_file(tmp_path, **program) -> Path:
    text = ROBOT.read_text() + "".join(f"  {k}: {v}\n" for k, v in program.items())
    path = tmp_path / "robot.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("safe, why", [
    (250, "outside joint 3's travel"), (1e6, "outside joint 3's travel"),
    (-100, "below the pen-up height"), (-15, "below the pen-up height"),
    (-210, "outside joint 3's travel")])
def test_a_travel_height_beyond_the_travel_or_below_pen_up_is_refused(tmp_path, safe, why):
    path = _robot_file(tmp_path, safe_z_mm=safe)
    with pytest.raises(VisionCalError) as e:
        load_robot_file(path)
    assert e.value.field == "program.safe_z_mm" and e.value.file == str(path)
    assert why in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("up, down, limits, safe, ok", [
    (-10, -20.5, "[-200, 0]", -10, True), (-10, -20.5, "[-200, 0]", 0, True),
    (10, 20.5, "[0, 200]", 5, True), (10, 20.5, "[0, 200]", 15, False),
    (10, 20.5, "[0, 200]", 30, False)])
def test_up_is_the_side_of_pen_up_whatever_joint_3s_sign(tmp_path, up, down, limits, safe, ok):
    """A controller counting joint 3 positive downwards has pen up below pen down in
    numbers: the travel height is checked on pen up's side, not by the sign."""
    text = ROBOT.read_text().replace("pen_up_mm: -10.0", f"pen_up_mm: {up}").replace(
        "pen_down_mm: -20.5", f"pen_down_mm: {down}")
    path = tmp_path / "robot.yaml"
    path.write_text(text.replace("program:\n", f"joint3_limits_mm: {limits}\nprogram:\n  "
                                                f"safe_z_mm: {safe}\n"))
    if ok:
        assert load_robot_file(path).program.safe_z_mm == safe
    else:
        with pytest.raises(VisionCalError, match="below the pen-up height"):
            load_robot_file(path)


@pytest.mark.parametrize("kind", sorted(READERS))
def test_a_writer_refuses_a_travel_height_into_the_table(tmp_path, kind):
    """A robot file made in code (not read) is checked by the writer too: no RAPID or eV+
    program travels "at the safe height" 79.5 mm below the pen-down height."""
    e = refused(kind, tmp_path, robot=robot_with(safe_z_mm=-100.0))
    assert e.field == "program.safe_z_mm"
