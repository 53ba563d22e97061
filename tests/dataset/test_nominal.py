"""One nominal, the user's robot file (issue 29 section 1, vision_cal/dataset/nominal.py):
however many calibrations sit between the robot file and this one (an informative plan is
placed with a pilot's model), calibration.json ``nominal``, the console's and the report's
controller offsets and export's are the robot file's; the pilot's model is the plan's
``starting_model``. The README rehearsal's version of this is in tests/test_rehearsal.py."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml

from vision_cal.commands.main import main
from vision_cal.dataset.nominal import (SIGN_CONVENTION, controller_offsets, nominal_blocks,
                                        rezero)
from vision_cal.report.headline import actions

ROOT = Path(__file__).resolve().parents[2]
ROBOT_FILE = {"L1_mm": 350.0, "L2_mm": 260.0, "joint_zero_deg": [0.0, 0.0],
              "base_mm": [-400.0, -250.0], "home_deg": [0.0, 0.0]}


def test_the_robot_file_is_the_nominal_and_the_pilot_the_starting_model():
    pilot = {"L1_mm": 344.0, "L2_mm": 259.9, "joint_zero_deg": [-2.57, -8.18],
             "base_mm": [-420.0, -230.0]}
    raw = {"design": {"nominal_robot": ROBOT_FILE, "pilot_calibration": "pilot_cal/c.json"}}
    b = nominal_blocks(raw, pilot)
    assert b["nominal"]["joint_zero_deg"] == [0.0, 0.0]
    assert b["starting_model"]["joint_zero_deg"] == [-2.57, -8.18]
    assert "pilot_cal/c.json" in b["starting_model"]["source"]
    # a session that is its own robot file, or says nothing: its robot block, no starting model
    assert nominal_blocks(raw, {k: ROBOT_FILE[k] for k in pilot}) == {
        "nominal": {k: ROBOT_FILE[k] for k in pilot}}
    assert nominal_blocks({}, pilot) == {"nominal": pilot}


def test_offsets_and_rezero_share_one_sign():
    """The joint turns to q + c: with c added the robot file's zero z_rf gives the
    calibrated link angle (q + c + z_cal == q + z_rf); a zero that moved by +d since is
    undone by adding -d."""
    doc = {"params": {"joint_zero_deg": [-2.5, -8.0]}, "nominal": {"joint_zero_deg": [0.5, 0.0]},
           "std": {"joint_zero_deg": [0.001, 0.002]}}
    o = controller_offsets(doc)
    assert [x["add_to_offset_deg"] for x in o] == [pytest.approx(3.0), pytest.approx(8.0)]
    assert "robot file's zero minus the calibrated zero" in SIGN_CONVENTION
    r = rezero(2, 0.04, -8.0)
    assert r["add_to_offset_deg"] == pytest.approx(-0.04)
    assert "add -0.0400 deg to joint 2's offset" in r["actions"][0]
    assert "z2 = -7.9600 deg" in r["actions"][1]


def test_a_calibration_of_a_plan_placed_with_a_pilot_tells_the_robot_files_offsets(
        tmp_path, capsys):
    """The seed paper's marks as an informative plan placed with a pilot's model (the
    session's robot block) designed from a robot file (design.nominal_robot)."""
    data = tmp_path / "plan"
    shutil.copytree(ROOT / "fixtures" / "paper_sm5", data)
    s = json.loads((data / "session.json").read_text())
    s["robot"].update(L1_mm=344.0, joint_zero_deg=[-2.5, -8.1], base_mm=[-420.0, -230.0])
    s["design"] = {"stage": "informative", "pilot_calibration": "pilot_cal/calibration.json",
                   "nominal_robot": ROBOT_FILE}
    (data / "session.json").write_text(json.dumps(s))
    assert main([str(data), "--out", str(tmp_path / "cal")]) == 0
    out = capsys.readouterr().out
    cal = json.loads((tmp_path / "cal" / "calibration.json").read_text())
    assert cal["nominal"]["joint_zero_deg"] == [0.0, 0.0]
    assert cal["starting_model"]["L1_mm"] == s["robot"]["L1_mm"]
    z = cal["params"]["joint_zero_deg"]
    line = next(ln for ln in out.splitlines()
                if ln.startswith("  - keep the robot file's model"))
    assert f"joint 1: {-z[0]:+.4f} deg" in line and f"joint 2: {-z[1]:+.4f} deg" in line
    assert "starting model" in out
    note = next(ln for ln in out.splitlines() if "starting model" in ln)
    assert "pilot_cal/calibration.json" in note and note.count("placed with") == 1, note
    a = actions(cal)
    assert [o["add_to_offset_deg"] for o in a["controller_offsets"]] == [
        pytest.approx(-z[0]), pytest.approx(-z[1])]
    assert a["olp_model"][2]["nominal"] == 0.0        # z1: the robot file's, not the pilot's
    assert main(["export", str(tmp_path / "cal" / "calibration.json"), "--yaml",
                 str(tmp_path / "c.yaml"), "-q"]) == 0
    y = yaml.safe_load((tmp_path / "c.yaml").read_text())
    assert y["controller_offsets"]["add_to_offset_deg"]["joint2"] == pytest.approx(-z[1])
