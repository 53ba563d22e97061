"""`vision-cal export` refuses a calibration.json whose units are implausible (issue 29:
"radian limits into the URDF"): lengths in metres, joint zeros or joint limits in radians,
one line naming the file and the field, nothing written. The check's owner is
estimate/plausible.py (verify uses the same)."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import pytest

from tests.test_verify_refuses import _doc, _metres, _radians

from vision_cal.commands.main import main

ROOT = Path(__file__).resolve().parents[2]
ROBOT = ROOT / "fixtures" / "robot_sm5.yaml"


def _nominal_metres(d):
    """Metres with the document's own nominal block (in mm) and no marks to compare."""
    d["nominal"] = copy.deepcopy(d["params"])
    _metres(d)
    del d["marks"]


def _limits_radians(d):
    d["joint_limits_deg"] = [[-math.radians(170), math.radians(170)],
                             [-math.radians(150), math.radians(150)]]


def _unmarked_metres(d):
    _metres(d)
    del d["marks"]


@pytest.mark.parametrize("edit, field, says, robot", [
    (_metres, "params", "metres", False),
    (_radians, "params", "radians", False),
    (_limits_radians, "joint_limits_deg", "radians", False),
    (_nominal_metres, "params.L1_mm", "metres", False),
    (_unmarked_metres, "params.L1_mm", "metres", True),
])
def test_export_refuses_implausible_units_naming_the_field(tmp_path, capsys, edit, field, says,
                                                           robot):
    d = _doc()
    edit(d)
    cal = tmp_path / "calibration.json"
    cal.write_text(json.dumps(d))
    before = cal.read_bytes()
    urdf, y = tmp_path / "robot.urdf", tmp_path / "c.yaml"
    argv = ["export", str(cal), "--urdf", str(urdf), "--yaml", str(y), "-q"]
    argv += ["--robot", str(ROBOT)] if robot else []
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{cal}: {field}: " in err[0] and says in err[0], err
    assert not urdf.exists() and not y.exists() and cal.read_bytes() == before


def test_the_same_file_in_mm_and_degrees_exports_its_limits_in_radians(tmp_path):
    d = _doc()
    d["joint_limits_deg"] = [[-170.0, 170.0], [-150.0, 150.0]]
    cal = tmp_path / "calibration.json"
    cal.write_text(json.dumps(d))
    urdf = tmp_path / "robot.urdf"
    assert main(["export", str(cal), "--urdf", str(urdf), "-q"]) == 0
    text = urdf.read_text()
    assert f'lower="{-math.radians(170):.9f}"' in text, text
