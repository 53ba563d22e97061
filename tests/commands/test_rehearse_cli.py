"""robot-template, the simulated robot file, the program follower and the sheet rebuilt
from sheet.json: what `vision-cal simulate` relies on, without rendering."""

from __future__ import annotations

import json
import logging

import numpy as np
import pytest

from vision_cal.commands.main import main
from vision_cal.errors import VisionCalError


def test_robot_template_ships_in_the_package_and_loads_clean(tmp_path, caplog):
    from vision_cal.dataset.robot import load_robot_file
    from vision_cal.world.rehearse import load_simulated_robot

    assert main(["robot-template", "-o", str(tmp_path / "robot.yaml"), "-q"]) == 0
    assert main(["robot-template", "--simulated", "-o", str(tmp_path / "true.yaml"), "-q"]) == 0
    with caplog.at_level(logging.WARNING):
        robot = load_robot_file(tmp_path / "robot.yaml")
        sim = load_simulated_robot(tmp_path / "true.yaml")
    assert not caplog.records                           # every field is a known one
    assert robot.require_pen_heights() == (-10.0, -20.5)
    # the hidden offsets are added to the robot file's values
    assert sim.params["L1_mm"] == pytest.approx(350.0 - 5.95)
    assert sim.params["joint_zero_deg"] == pytest.approx([-2.57, -8.13])
    assert sim.params["base_mm"] == pytest.approx([-420.0, -230.0])
    assert sim.truth.backlash_deg == (0.0, 0.1)
    # an existing file is not replaced
    assert main(["robot-template", "-o", str(tmp_path / "robot.yaml"), "-q"]) == 2


@pytest.mark.parametrize("edit, field", [
    ({"hiden": {}}, "hiden"),
    ({"hidden": {"joint_zero_deg": [1.0]}}, "hidden.joint_zero_deg"),
    ({"hidden": {"effects": [{"name": "joint_wobble", "joint": 2}]}}, "hidden.effects[0]"),
    ({"hidden": {"controller": "magic"}}, "hidden.controller"),
    ({"camera": {"photos": 0}}, "camera.photos"),
    ({"print": {"deviation_rms_mm": -0.1}}, "print.deviation_rms_mm"),
    ({"print": {"toner": 0.1}}, "print.toner"),
])
def test_a_bad_simulated_robot_is_one_line_naming_the_field(tmp_path, capsys, edit, field):
    import yaml

    from vision_cal.templates import template_text

    (tmp_path / "robot.yaml").write_text(template_text("robot"))
    doc = yaml.safe_load(template_text("simulated"))
    doc.update(edit)
    (tmp_path / "true.yaml").write_text(yaml.safe_dump(doc))
    (tmp_path / "plan").mkdir()
    rc = main(["simulate", str(tmp_path / "plan"), "--truth", str(tmp_path / "true.yaml"),
               "--out", str(tmp_path / "plan")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert "true.yaml" in err[0] and field in err[0], err


@pytest.mark.parametrize("kw", [dict(size="A2"), dict(size="A4", landscape=False,
                                                      dictionary="DICT_4X4_50"),
                                dict(size=None, custom_mm=(500, 350), marker_mm=24, pitch_mm=90)])
def test_the_printed_sheet_is_rebuilt_from_its_sheet_json(kw):
    from vision_cal.sheet import make_layout
    from vision_cal.sheet.png import rasterise
    from vision_cal.sheet.rebuild import layout_from_sheet_json

    printed = make_layout(**kw)
    doc = json.loads(json.dumps(printed.to_sheet_json()))   # as read back from the file
    again = layout_from_sheet_json(doc)
    assert again.sheet_id == printed.sheet_id
    assert np.array_equal(rasterise(again, 25.4), rasterise(printed, 25.4))
    # a sheet that is not this print is refused, naming why
    doc["markers"][0]["corners_mm"] = [[x + 1.0, y] for x, y in doc["markers"][0]["corners_mm"]]
    with pytest.raises(VisionCalError, match="sheet_id"):
        layout_from_sheet_json(doc)
    doc["printed"]["generator"] = "someone else"
    with pytest.raises(VisionCalError, match="printed.generator"):
        layout_from_sheet_json(doc)


def test_the_program_is_followed_and_must_be_the_plans(tmp_path):
    """The pen-down points of a SPEL+ program matched in order to session.json's marks,
    each with the points driven through since the previous mark (its via points)."""
    from vision_cal.dataset.robot import load_robot_file
    from vision_cal.plan.calibration_plan import PlannedMark
    from vision_cal.program import program_points, write_program
    from vision_cal.world.rehearse import marks_from_program
    from vision_cal.templates import template_text

    (tmp_path / "robot.yaml").write_text(template_text("robot"))
    robot = load_robot_file(tmp_path / "robot.yaml")
    plan = [PlannedMark("a", (10.0, 20.0), "calibration", (1, -1), ((7.0, 23.0),)),
            PlannedMark("b", (-5.0, 40.0), "calibration", (-1, 1), ((-2.0, 37.0),))]
    prg = write_program("spel", tmp_path / "p.prg", program_points(plan), robot, title="t")
    marks = [m.to_json() for m in plan]
    got = marks_from_program(prg, marks, pen_down_mm=robot.pen_down_mm)
    assert [m.id for m in got] == ["a", "b"]
    assert got[0].via_deg == ((0.0, 0.0), (7.0, 23.0))   # home, then the via point
    assert got[1].via_deg == ((-2.0, 37.0),)
    marks[1]["joints_deg"] = [-5.0, 41.0]
    with pytest.raises(VisionCalError, match="not this plan's"):
        marks_from_program(prg, marks, pen_down_mm=robot.pen_down_mm)


def test_spel_options_pen_output_jump_limz_motor_off(tmp_path):
    """The robot file's pen output bit, safe height and Motor Off reach the program, and
    the program still draws the plan: the follower finds every mark with its via point,
    the approach moves stay Go (a Jump only travels to a mark's first point)."""
    import yaml

    from vision_cal.dataset.robot import load_robot_file
    from vision_cal.plan.calibration_plan import PlannedMark
    from vision_cal.program import program_points, write_program
    from vision_cal.world.rehearse import marks_from_program
    from vision_cal.templates import template_text

    doc = yaml.safe_load(template_text("robot"))
    doc["program"].update(pen_output_bit=9, safe_z_mm=-2.0, motor_off=True)
    (tmp_path / "robot.yaml").write_text(yaml.safe_dump(doc))
    robot = load_robot_file(tmp_path / "robot.yaml")
    plan = [PlannedMark("a", (10.0, 20.0), "target", (1, -1), ((7.0, 23.0),)),
            PlannedMark("b", (-5.0, 40.0), "target", (-1, 1), ((-2.0, 37.0),))]
    prg = write_program("spel", tmp_path / "p.prg", program_points(plan), robot, title="t")
    text = prg.read_text()
    assert text.count("    On 9") == 2 and text.count("    Off 9") == 2
    assert "JA(7.0000, 23.0000, -10.000, 0.0000) LimZ -2.000" in text
    assert "Go JA(10.0000, 20.0000, -10.000" in text          # onto the mark: Go
    assert "-20.500" not in text                               # joint 3 never lowers the pen
    assert text.rstrip().endswith("Motor Off\nFend")
    assert "Do not edit the points: the calibration" not in text   # a targets program
    got = marks_from_program(prg, [m.to_json() for m in plan], pen_down_mm=robot.pen_down_mm,
                             pen_bit=9)
    assert [(m.id, m.via_deg[-1]) for m in got] == [("a", (7.0, 23.0)), ("b", (-2.0, 37.0))]
    doc["program"]["pen_output_bit"] = "nine"
    (tmp_path / "robot.yaml").write_text(yaml.safe_dump(doc))
    with pytest.raises(VisionCalError, match="program.pen_output_bit"):
        load_robot_file(tmp_path / "robot.yaml")


def test_the_blank_sheet_is_photographed_printed_off_its_layout(tmp_path, capsys):
    """`vision-cal simulate SHEET.json` photographs the blank sheet (no marks) for a survey,
    from several places, printed as the simulated robot's ``print`` says: truth.json's
    markers as printed lie off the layout by the RMS asked (0.15 mm over the paper, about
    as much at the markers), the same print on every rehearsal of one sheet (its field
    drawn from the sheet's id, not the run's seed), and none with ``deviation_rms_mm: 0``.
    A small camera keeps it cheap."""
    import yaml

    from vision_cal.templates import template_text

    assert main(["sheet", "--size", "A4", "--out", str(tmp_path / "sheet"), "-q"]) == 0
    (tmp_path / "robot.yaml").write_text(template_text("robot"))
    doc = yaml.safe_load(template_text("simulated"))
    assert doc["print"] == {"deviation_rms_mm": 0.0}          # the template: an exact print
    doc["camera"].update(size_px=[320, 240], f_px=350.0)
    doc["print"]["deviation_rms_mm"] = 0.15
    (tmp_path / "true.yaml").write_text(yaml.safe_dump(doc))
    sheet = json.loads((tmp_path / "sheet" / "sheet.json").read_text())
    layout = {m["id"]: np.array(m["corners_mm"]) for m in sheet["markers"]}
    off = []
    for k, (seed, n) in enumerate(((1, 3), (2, 1))):
        out = tmp_path / f"survey{k}"
        assert main(["simulate", str(tmp_path / "sheet" / "sheet.json"), "--truth",
                     str(tmp_path / "true.yaml"), "--out", str(out), "--photos", str(n),
                     "--seed", str(seed)]) == 0
        assert f"the blank sheet photographed from {n} place{'s' if n != 1 else ''}" in capsys.readouterr().out
        truth = json.loads((out / "truth.json").read_text())
        assert len(list(out.glob("IMG_*.png"))) == n == len(truth["camera"]["T_cam_sheet"])
        assert truth["print"]["rms_mm"] == pytest.approx(0.15, rel=1e-6)
        off.append(np.concatenate([np.array(truth["print"]["markers"][str(i)]) - c
                                   for i, c in layout.items()]))
    assert np.array_equal(off[0], off[1])                      # one sheet, one print
    assert 0.05 < float(np.sqrt(np.mean(np.sum(off[0] ** 2, axis=1)))) < 0.3
    doc["print"]["deviation_rms_mm"] = 0.0
    (tmp_path / "true.yaml").write_text(yaml.safe_dump(doc))
    assert main(["simulate", str(tmp_path / "sheet" / "sheet.json"), "--truth",
                 str(tmp_path / "true.yaml"), "--out", str(tmp_path / "exact"), "--photos", "1",
                 "-q"]) == 0
    assert json.loads((tmp_path / "exact" / "truth.json").read_text())["print"] is None


def test_a_sheet_is_read_from_the_session_json_designed_on_it(tmp_path):
    """`survey --sheet` (and every --sheet) takes what the user has: a session.json carries
    the sheet it was designed on, read as the sheet.json itself."""
    from vision_cal.dataset.session import load_sheet_file

    assert main(["sheet", "--size", "A4", "--out", str(tmp_path / "sheet"), "-q"]) == 0
    sheet = json.loads((tmp_path / "sheet" / "sheet.json").read_text())
    (tmp_path / "session.json").write_text(json.dumps({"format": "vision-cal/1",
                                                       "sheet": sheet, "marks": []}))
    a = load_sheet_file(tmp_path / "sheet" / "sheet.json")
    b = load_sheet_file(tmp_path / "session.json")
    assert a.corners_by_id().keys() == b.corners_by_id().keys()
    assert all(np.array_equal(a.corners_by_id()[i], b.corners_by_id()[i])
               for i in a.corners_by_id())
    sheet["markers"][0]["corners_mm"] = "x"
    (tmp_path / "session.json").write_text(json.dumps({"format": "vision-cal/1",
                                                       "sheet": sheet, "marks": []}))
    with pytest.raises(VisionCalError, match="sheet.markers"):
        load_sheet_file(tmp_path / "session.json")
