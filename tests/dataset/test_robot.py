"""The robot file: valid files read, every bad field is one line naming file and field."""

import json

import pytest

from vision_cal.dataset.robot import load_robot_file
from vision_cal.errors import VisionCalError
from tests.conftest import ROOT

FIXTURE = ROOT / "fixtures" / "robot_sm5.yaml"


def _base() -> dict:
    return {"L1_mm": 350.0, "L2_mm": 260.0, "joint_zero_deg": [0.0, 0.0],
            "base_mm": [-400.0, -250.0]}


def _write(tmp_path, d, name="robot.json"):
    p = tmp_path / name
    p.write_text(json.dumps(d))
    return p


def test_fixture_reads_with_every_field():
    r = load_robot_file(FIXTURE)
    assert r.name == "SM5" and r.nominal.L1_mm == 350.0 and r.elbows == (1, -1)
    assert r.tolerance.joint_zero_deg == (4.0, 10.0) and r.require_pen_heights() == (-10.0, -20.5)
    assert r.program.speed_percent == 20 and r.joint_limits_deg[1] == (-150.0, 150.0)


def test_minimal_json_takes_defaults(tmp_path):
    r = load_robot_file(_write(tmp_path, _base()))
    assert r.nominal.home_deg == (0.0, 0.0) and r.tolerance.base_mm == 30.0
    with pytest.raises(VisionCalError, match="pen_up_mm"):
        r.require_pen_heights()


@pytest.mark.parametrize("patch, field", [
    ({"L1_mm": -1}, "L1_mm"),
    ({"joint_zero_deg": [0.0]}, "joint_zero_deg"),
    ({"base_mm": ["a", 1]}, "base_mm[0]"),
    ({"joint_limits_deg": [[10, -10], [-150, 150]]}, "joint_limits_deg[0]"),
    ({"joint_limits_deg": [[-10, 10]]}, "joint_limits_deg"),
    ({"speed_limits_deg_s": [90, 0]}, "speed_limits_deg_s[1]"),
    ({"elbows": [1, 2]}, "elbows[1]"),
    ({"elbows": []}, "elbows"),
    ({"pen_up_mm": -10}, "pen_down_mm"),
    ({"pen_up_mm": -10, "pen_down_mm": -10}, "pen_down_mm"),
    ({"joint3_limits_mm": [0, -100]}, "joint3_limits_mm"),
    ({"joint3_limits_mm": [-100, 0], "pen_up_mm": -10, "pen_down_mm": -120}, "pen_down_mm"),
    ({"placement_tolerance": {"base_mm": -5}}, "placement_tolerance.base_mm"),
    ({"placement_tolerance": {"joint_zero_deg": [1, float("nan")]}},
     "placement_tolerance.joint_zero_deg[1]"),
    ({"program": {"speed_percent": 150}}, "program.speed_percent"),
    ({"program": {"power": "max"}}, "program.power"),
    ({"home_deg": [0, 160]}, "home_deg"),
])
def test_bad_field_is_one_line_naming_it(tmp_path, patch, field):
    d = dict(_base(), **patch)
    p = tmp_path / "robot.json"
    p.write_text(json.dumps(d, allow_nan=True))
    with pytest.raises(VisionCalError) as e:
        load_robot_file(p)
    assert e.value.file == str(p) and e.value.field == field, str(e.value)
    assert "\n" not in str(e.value)


def test_missing_field_and_bad_yaml(tmp_path):
    d = _base()
    del d["L2_mm"]
    with pytest.raises(VisionCalError, match="L2_mm: missing"):
        load_robot_file(_write(tmp_path, d))
    p = tmp_path / "r.yaml"
    p.write_text("L1_mm: [1, 2\n")
    with pytest.raises(VisionCalError, match="not valid YAML"):
        load_robot_file(p)
    p.write_text("!!python/object/apply:os.system ['true']\n")
    with pytest.raises(VisionCalError, match="not valid YAML"):
        load_robot_file(p)


def test_cli_exit_2_names_the_field(tmp_path, capsys):
    from vision_cal.commands.main import main

    p = _write(tmp_path, dict(_base(), elbows=[3]))
    (tmp_path / "sheet.json").write_text("{}")
    rc = main(["design", str(p), "--sheet", str(tmp_path / "sheet.json"), "--out",
               str(tmp_path / "plan")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err.count("\n") == 0 and "elbows[0]" in err and str(p) in err
    assert not (tmp_path / "plan").exists()
