"""`vision-cal design --placements N`: the sheet turned about joint 1 (issue #21)."""

import json

import numpy as np

from tests.design.conftest import ROBOT, border_sheet
from vision_cal.dataset.robot import load_robot_file
from vision_cal.design.placements import joint1_span_deg, plan_placements
from vision_cal.model.kinematics import ScaraParams, forward


def test_a_turned_placement_is_the_same_robot_in_the_turned_sheet():
    robot = load_robot_file(ROBOT)
    places = plan_placements(robot, border_sheet(), 3)
    lo, hi = joint1_span_deg(robot.nominal, border_sheet().extent_mm)
    deltas = [p["delta_deg"] for p in places]
    assert deltas[0] == 0 and sorted(np.abs(deltas[1:])) == [hi - lo, hi - lo]
    n = robot.nominal
    for p in places:
        # the sheet turned by delta about the base: joint 1 turned by delta draws on the
        # same printed point as before the turn
        b = p["robot"]
        pk = ScaraParams(n.L1_mm, n.L2_mm, *b["joint_zero_deg"], *b["base_mm"])
        p0 = ScaraParams(n.L1_mm, n.L2_mm, *n.joint_zero_deg, *n.base_mm)
        q = np.array([[lo + 10, -60.0]])
        np.testing.assert_allclose(forward(pk, q + [p["delta_deg"], 0]), forward(p0, q),
                                   atol=1e-9)
        assert p["q1_range_deg"][0] >= robot.joint_limits_deg[0][0]
        assert p["q1_range_deg"][1] <= robot.joint_limits_deg[0][1]


def test_design_placements_writes_one_design_per_placement(tmp_path, sheet_json, monkeypatch):
    """The wiring: one robot file and one design per placement (the pilot design itself is
    tested in test_pilot.py; here it is replaced by a stub that records its robot file)."""
    import vision_cal.design.placements as placements
    from vision_cal.commands.main import main

    seen = []

    class R:
        n_marks = 0

    def stub(robot_path, sheet_path, out, **kw):
        seen.append(load_robot_file(robot_path).nominal.joint_zero_deg)
        return R()

    monkeypatch.setattr(placements, "design_stage", stub)
    assert main(["design", str(ROBOT), "--sheet", str(sheet_json), "--out", str(tmp_path),
                 "--placements", "3", "--program", "csv", "-q"]) == 0
    places = json.loads((tmp_path / "placements.json").read_text())["placements"]
    assert [tuple(p["robot"]["joint_zero_deg"]) for p in places] == seen
    assert len(set(seen)) == 3
    assert all((tmp_path / f"place{k}" / "robot.yaml").exists() for k in (1, 2, 3))
    assert main(["design", str(ROBOT), "--sheet", str(sheet_json), "--out", str(tmp_path / "x"),
                 "--placements", "9", "-q"]) == 2    # no room for 9: one line, exit 2
