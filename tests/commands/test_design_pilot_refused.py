"""``vision-cal design --pilot/--verify`` reads the calibration.json given as every reader
does (``CalibrationResult``) and refuses one it cannot plan from in one line naming the file
and the field (exit 2, nothing written): the robot-frame file of several placements, lengths
in metres, a pilot whose verdict is not reliable."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from tests.test_verify_refuses import _doc, _metres, _set
from vision_cal.commands.main import main

ROOT = Path(__file__).resolve().parents[2]
ROBOT = str(ROOT / "fixtures" / "robot_sm5.yaml")


def _placements(d):
    d.update(frame="robot", placements=[{"folder": "place0"}, {"folder": "place1"}])


@pytest.mark.parametrize("option", ["--pilot", "--verify"])
@pytest.mark.parametrize("edit, field, says", [
    (_placements, None, "place1/calibration.json"),
    (_metres, "params.L1_mm", "metres instead of millimetres"),
])
def test_design_refuses_a_calibration_it_cannot_plan_from(option, edit, field, says, tmp_path,
                                                          capsys):
    doc = copy.deepcopy(_doc())
    edit(doc)
    cal = tmp_path / "calibration.json"
    cal.write_text(json.dumps(doc))
    out = tmp_path / "out"
    code = main(["design", ROBOT, "--sheet", str(tmp_path / "sheet.json"), "--out", str(out),
                 "-q", option, str(cal)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith(f"vision-cal: error: {cal}: " + (f"{field}: " if field else ""))
    assert says in err[0], err[0]
    assert not out.exists()


@pytest.mark.parametrize("verdict, refused", [
    ({"status": "not reliable", "reasons": ["the robot changed while drawing"],
      "reason_codes": ["drift"], "reason_levels": ["not reliable"]}, True),
    ({"status": "check", "reasons": ["few marks"]}, False),
    ({"status": "check", "within_valid_for": "check", "reasons": ["x", "y"],
      "reason_codes": ["not_identified", "print_one_place"]}, False),
    ({"status": "ready", "reasons": []}, False),
])
def test_design_refuses_only_a_pilot_not_reliable(verdict, refused, tmp_path, capsys):
    """A pilot whose verdict is "not reliable" is refused naming verdict.status and its
    reason; one "check" (for whatever reason: the informative plan needs its model to
    millimetres) or ready passes that check (and stops at the sheet, not given here)."""
    doc = _doc()
    _set(["verdict"], verdict)(doc)
    cal = tmp_path / "calibration.json"
    cal.write_text(json.dumps(doc))
    sheet = tmp_path / "sheet.json"
    code = main(["design", ROBOT, "--sheet", str(sheet), "--out", str(tmp_path / "out"), "-q",
                 "--pilot", str(cal)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    if refused:
        assert f"{cal}: verdict.status: " in err[0] and "robot changed" in err[0], err[0]
    else:
        assert f"{cal}" not in err[0] and str(sheet) in err[0], err[0]
