"""The robot's joint limits travel with the calibration (issue 18 section 5): recorded in
calibration.json from the session, used by ``plan`` without ``--robot``, written into the
URDF (``export --robot`` for a robot file's)."""

import csv
import json
import math
import re
import shutil
from pathlib import Path

import pytest

from vision_cal.commands.main import main

ROOT = Path(__file__).resolve().parents[2]
TARGETS = ROOT / "fixtures" / "targets_origin.csv"


def _plan_q1(plan_csv):
    with open(plan_csv) as f:
        return {r["id"]: float(r["q1_deg"]) for r in csv.DictReader(f)}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """(calibration.json without limits, the planned q1 of each target, a calibration.json
    whose session's robot block limits joint 1 to just above the origin target's q1)."""
    tmp = tmp_path_factory.mktemp("limits")
    assert main([str(ROOT / "fixtures" / "paper_sm5"), "--out", str(tmp / "free"), "-q"]) == 0
    assert main(["plan", str(tmp / "free" / "calibration.json"), str(TARGETS), "-o",
                 str(tmp / "free.csv"), "-q", "--force"]) == 3   # far: partial
    q1 = _plan_q1(tmp / "free.csv")
    src = tmp / "data"
    shutil.copytree(ROOT / "fixtures" / "paper_sm5", src)
    doc = json.loads((src / "session.json").read_text())
    lo = q1["origin"] + 0.5                      # the origin needs q1 below the limit
    doc["robot"]["joint_limits_deg"] = [[lo, 175.0], [-150.0, 150.0]]
    (src / "session.json").write_text(json.dumps(doc))
    assert main([str(src), "--out", str(tmp / "lim"), "-q"]) == 0
    return tmp / "free" / "calibration.json", q1, tmp / "lim" / "calibration.json", lo


def test_limits_are_recorded_and_plan_honours_them(runs, tmp_path):
    _, q1, cal, lo = runs
    doc = json.loads(cal.read_text())
    assert doc["joint_limits_deg"] == [[lo, 175.0], [-150.0, 150.0]]
    main(["plan", str(cal), str(TARGETS), "-o", str(tmp_path / "p.csv"), "-q"])
    planned = _plan_q1(tmp_path / "p.csv")
    assert "origin" not in planned                 # outside joint 1's limits, without --robot
    assert all(lo <= v <= 175.0 for v in planned.values())
    failed = (tmp_path / "p.failed.csv").read_text()
    assert "origin" in failed


def test_the_urdf_gets_the_real_limits(runs, tmp_path):
    free, _, cal, lo = runs
    assert main(["export", str(cal), "--urdf", str(tmp_path / "r.urdf"), "-q"]) == 0
    lows = [float(v) for v in re.findall(r'lower="([-0-9.]+)"', (tmp_path / "r.urdf").read_text())]
    assert lows == pytest.approx([math.radians(lo), math.radians(-150.0)], abs=1e-8)
    # a robot file's limits win when given
    assert main(["export", str(free), "--urdf", str(tmp_path / "f.urdf"), "--robot",
                 str(ROOT / "fixtures" / "robot_sm5.yaml"), "-q"]) == 0
    his = [float(v) for v in re.findall(r'upper="([-0-9.]+)"', (tmp_path / "f.urdf").read_text())]
    assert his == pytest.approx([math.radians(170.0), math.radians(150.0)], abs=1e-8)
