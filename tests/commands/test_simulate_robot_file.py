"""`vision-cal simulate` is the robot file (issue 29, section 4): its tool and joint 4, its
joint limits, the program it was told to run and nothing else, targets matching the plan.
No pyrender: the photographer is replaced by a blank photo where a test needs the world."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from vision_cal.commands.main import main
from vision_cal.errors import VisionCalError
from vision_cal.templates import template_text


def _robot(tmp_path, **edit) -> Path:
    doc = yaml.safe_load(template_text("robot"))
    doc.update(edit)
    p = tmp_path / "robot.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


def _simulated(tmp_path, **hidden) -> Path:
    doc = yaml.safe_load(template_text("simulated"))
    doc["hidden"] = {"controller": "kinematic", "repeatability_mm": 0.0, **hidden}
    doc["camera"] = {"photos": 1}
    p = tmp_path / "true.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


def _program(tmp_path, plan, robot_path, name="p.prg", kind="spel"):
    from vision_cal.dataset.robot import load_robot_file
    from vision_cal.program import program_points, write_program

    robot = load_robot_file(robot_path)
    return write_program(kind, tmp_path / name, program_points(plan), robot, title="t"), robot


def _plan():
    from vision_cal.plan.calibration_plan import PlannedMark
    return [PlannedMark("a", (10.0, 20.0), "calibration", (1, -1), ((7.0, 23.0),)),
            PlannedMark("b", (-5.0, 40.0), "calibration", (-1, 1), ((-2.0, 37.0),))]


def test_the_simulated_pen_is_the_robot_files_tool(tmp_path):
    """A robot file with tool_mm [25, 0]: the true robot carries it (not a pen on the
    flange axis), and hidden.tool_mm offsets it."""
    from vision_cal.world.rehearse import load_simulated_robot

    _robot(tmp_path, tool_mm=[25.0, 0.0])
    sim = load_simulated_robot(_simulated(tmp_path, tool_mm=[0.5, -0.25]))
    assert sim.truth.tool_mm == pytest.approx((25.5, -0.25))
    assert sim.params["tool_mm"] == pytest.approx([25.5, -0.25])


def test_the_program_s_joint_4_turns_the_tool(tmp_path):
    """Joint 4 as the program commands it reaches each mark: a 90 deg turn moves a 25 mm
    tool by 25 sqrt 2 mm on the paper."""
    from vision_cal.world.rehearse import marks_from_program

    robot_path = _robot(tmp_path, tool_mm=[25.0, 0.0], j4_deg=0.0)
    plan = _plan()
    prg, robot = _program(tmp_path, plan, robot_path)
    turned = prg.with_name("q.prg")
    text = prg.read_text().replace(", -20.500, 0.0000)", ", -20.500, 90.0000)")
    turned.write_text(text.replace(", -10.000, 0.0000)", ", -10.000, 90.0000)"))
    marks = [m.to_json() for m in plan]
    a = marks_from_program(prg, marks, pen_down_mm=robot.pen_down_mm, robot=robot)
    b = marks_from_program(turned, marks, pen_down_mm=robot.pen_down_mm, robot=robot)
    assert [m.j4_deg for m in a] == [0.0, 0.0] and [m.j4_deg for m in b] == [90.0, 90.0]


@pytest.mark.parametrize("bad, what", [
    ("    Go JA(500.0000, 20.0000, -10.000, 0.0000)", "joint 1 at 500 deg"),
    ("    Go JA(10.0000, -151.0000, -10.000, 0.0000)", "joint 2 at -151 deg"),
    ("    Go JA(10.0000, 20.0000, -10.000, 400.0000)", "joint 4 at 400 deg"),
    ("    Go JA(10.0000, 20.0000, -250.000, 0.0000)", "joint 3 at -250 mm"),
    ("    Move P1", "does not know"),
    ("    Go JA(10.0000, 20.0000, -10.000, 0.0000) CP", "does not know"),
    ("    Arch 0, 10, 10", "does not know"),
])
def test_a_program_the_robot_file_would_not_run_is_refused(tmp_path, bad, what):
    from vision_cal.world.rehearse import marks_from_program

    prg, robot = _program(tmp_path, _plan(), _robot(tmp_path))
    lines = prg.read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if "Function main" in ln) + 2
    lines.insert(k, bad)
    prg.write_text("\r\n".join(lines) + "\r\n")
    with pytest.raises(VisionCalError, match=f"line {k + 1}: .*{what}") as e:
        marks_from_program(prg, [m.to_json() for m in _plan()], pen_down_mm=robot.pen_down_mm,
                           robot=robot)
    assert str(prg) in str(e.value) and "\n" not in str(e.value)


def test_the_point_list_is_held_to_the_limits_too(tmp_path):
    from vision_cal.world.rehearse import marks_from_program

    prg, robot = _program(tmp_path, _plan(), _robot(tmp_path), name="p_points.csv", kind="csv")
    text = prg.read_text().replace("10.000000,20.000000", "10.000000,160.000000")
    prg.write_text(text)
    with pytest.raises(VisionCalError, match=r"row \d+: joint 2 at 160 deg"):
        marks_from_program(prg, [m.to_json() for m in _plan()], pen_down_mm=robot.pen_down_mm,
                           robot=robot)


def _sheet(tmp_path) -> Path:
    assert main(["sheet", "--size", "A3", "--out", str(tmp_path / "sheet"), "-q"]) == 0
    return tmp_path / "sheet" / "sheet.json"


def test_a_folder_without_its_program_is_refused(tmp_path, capsys):
    """No fallback to session.json's marks: the rehearsal runs the robot's program."""
    _robot(tmp_path)
    folder = tmp_path / "plan"
    folder.mkdir()
    session = {"format": "vision-cal/1", "sheet": json.loads(_sheet(tmp_path).read_text()),
               "marks": [m.to_json() for m in _plan()]}
    (folder / "session.json").write_text(json.dumps(session))
    rc = main(["simulate", str(folder), "--truth", str(_simulated(tmp_path)), "--out",
               str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "no robot program" in err[0] and str(folder) in err[0]
    assert not (tmp_path / "out").exists()


def test_targets_whose_ids_are_not_the_plans_are_refused(tmp_path, capsys):
    from vision_cal.world.rehearse import _same_ids

    _same_ids(["a", "b"], ["b", "a"], Path("p.csv"), Path("t.csv"))       # same marks
    with pytest.raises(VisionCalError, match="targets not in the plan.*: c") as e:
        _same_ids(["a", "b"], ["a", "b", "c"], Path("p.csv"), Path("t.csv"))
    assert str(e.value).startswith("t.csv: ")
    with pytest.raises(VisionCalError, match="planned marks not among the targets: b"):
        _same_ids(["a", "b"], ["a"], Path("p.csv"), Path("t.csv"))


def test_targets_program_with_other_ids_exits_2(tmp_path, capsys):
    robot_path = _robot(tmp_path)
    assert main(["sheet", "--size", "A3", "--out", str(tmp_path / "sheet"), "-q"]) == 0
    prg, _ = _program(tmp_path, _plan(), robot_path, name="targets_plan.prg")
    (tmp_path / "targets_plan.csv").write_text(
        "id,q1_deg,q2_deg,approach1,approach2\na,10,20,1,-1\nb,-5,40,-1,1\n")
    (tmp_path / "targets.csv").write_text("id,x_mm,y_mm\na,0,0\nz,1,1\n")
    rc = main(["simulate", str(prg), "--truth", str(_simulated(tmp_path)), "--sheet",
               str(tmp_path / "sheet" / "sheet.json"), "--targets",
               str(tmp_path / "targets.csv"), "--out", str(tmp_path / "hits")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert "targets.csv" in err[0] and "z" in err[0] and "b" in err[0]


class _Blank:
    """The photographer without pyrender: a grey photo (the tests read truth.json)."""

    def __init__(self, *, size_px, K):
        self.size = size_px

    def photograph(self, tex, **kw):
        return np.full((self.size[1], self.size[0], 3), 128, np.uint8)

    def close(self):
        pass


def test_simulate_draws_with_the_robot_files_tool_and_joint_4(tmp_path, monkeypatch):
    """The whole command: a targets program drawn by a robot file with a 25 mm tool lands
    25 mm from the flange, along the flange's direction (truth.json's marks); the program's
    joint 4 at 90 deg turns it a quarter turn."""
    import vision_cal.world.rehearse as rehearse
    from vision_cal.world.truth_model import TrueRobot

    monkeypatch.setattr(rehearse, "Photographer", _Blank)
    robot_path = _robot(tmp_path, tool_mm=[25.0, 0.0])
    sheet = _sheet(tmp_path)
    prg, _ = _program(tmp_path, _plan(), robot_path, name="targets_plan.prg")
    text = prg.read_text()
    prg.write_text(text.replace("-20.500, 0.0000)  ' b pen down", "-20.500, 90.0000)  ' b pen down"))
    (tmp_path / "targets_plan.csv").write_text(
        "id,q1_deg,q2_deg,approach1,approach2\na,10,20,1,-1\nb,-5,40,-1,1\n")
    assert main(["simulate", str(prg), "--truth", str(_simulated(tmp_path)), "--sheet",
                 str(sheet), "--out", str(tmp_path / "out"), "-q"]) == 0
    truth = json.loads((tmp_path / "out" / "truth.json").read_text())
    assert truth["params"]["tool_mm"] == [25.0, 0.0]
    q = np.array([p.joints_deg for p in _plan()])
    bare = TrueRobot.from_json({**truth["params"], "tool_mm": [0.0, 0.0]}, truth["effects"])
    flange = bare.pen_mm(q, np.ones_like(q))
    got = np.array([truth["marks"][k] for k in ("a", "b")])
    z = np.radians(truth["params"]["joint_zero_deg"])
    ang = np.radians(q.sum(axis=1) + [0.0, 90.0]) + z.sum()   # link 2's direction + joint 4
    assert np.allclose(got - flange, 25.0 * np.column_stack([np.cos(ang), np.sin(ang)]),
                       atol=1e-6), got - flange


def test_the_robot_files_speed_limits_shape_the_simulated_motion(tmp_path, monkeypatch):
    """The simulated controller follows a trajectory planned with the robot file's speed
    and acceleration limits, not the defaults."""
    import vision_cal.world.rehearse as rehearse

    seen = {}

    class Stop(Exception):
        pass

    def world(truth, **kw):
        seen.update(kw)
        raise Stop

    monkeypatch.setattr(rehearse, "simulated_world", world)
    robot_path = _robot(tmp_path, speed_limits_deg_s=[30.0, 45.0],
                        accel_limits_deg_s2=[100.0, 150.0])
    prg, _ = _program(tmp_path, _plan(), robot_path, name="targets_plan.prg")
    (tmp_path / "targets_plan.csv").write_text(
        "id,q1_deg,q2_deg,approach1,approach2\na,10,20,1,-1\nb,-5,40,-1,1\n")
    sim = yaml.safe_load(_simulated(tmp_path).read_text())
    sim["hidden"]["controller"] = "smc"
    (tmp_path / "true.yaml").write_text(yaml.safe_dump(sim))
    with pytest.raises(Stop):
        rehearse.simulate_session(prg, tmp_path / "true.yaml", tmp_path / "out",
                                  sheet_json=_sheet(tmp_path))
    assert seen["vmax_deg_s"] == (30.0, 45.0) and seen["amax_deg_s2"] == (100.0, 150.0)
