"""`vision-cal design` with an off-axis tool: the informative plan turns joint 4 and keeps
every mark on free paper on the true robot (issue #21)."""

import json

import numpy as np

from tests.design.conftest import ROBOT, border_sheet
from vision_cal.plan.calibration_plan import sheet_clearance_mm
from vision_cal.world.truth_model import TrueRobot

TOOL = [21.0, -7.0]
TRUTH = TrueRobot.from_json(
    {"L1_mm": 344.05, "L2_mm": 259.87, "joint_zero_deg": [-2.57, -8.13],
     "base_mm": [-420.0, -230.0], "tool_mm": TOOL})


def test_design_turns_joint4_and_marks_stay_on_free_paper(tmp_path, pilot_dir, sheet_json):
    from vision_cal.design.stage import design_stage
    from vision_cal.actions.pipeline import calibrate_dataset

    rng = np.random.default_rng(4)
    s = json.loads((pilot_dir / "session.json").read_text())
    q = np.array([m["joints_deg"] for m in s["marks"]])
    xy = TRUTH.pen_mm(q) + rng.normal(0, 0.02, q.shape)   # the pilot at j4 = 0
    for m, p in zip(s["marks"], xy):
        m["measured_mm"] = p.tolist()
    (tmp_path / "pilot").mkdir()
    (tmp_path / "pilot" / "session.json").write_text(json.dumps(s))
    cal = calibrate_dataset(tmp_path / "pilot", out_dir=tmp_path / "pilot_cal").out_path
    robot = tmp_path / "robot.yaml"
    robot.write_text(ROBOT.read_text() + f"\ntool_mm: [{TOOL[0] + 1.5}, {TOOL[1] - 1.0}]\n")
    r = design_stage(robot, sheet_json, tmp_path / "plan", pilot=cal, program="spel")
    plan = json.loads((tmp_path / "plan" / "session.json").read_text())
    j4 = np.array([m["j4_deg"] for m in plan["marks"]])
    assert len(set(j4)) >= 3 and r.info["joint4_turns"]
    q = np.array([m["joints_deg"] for m in plan["marks"]])
    drawn = TRUTH.pen_mm(np.column_stack([q, j4]))
    # the rough tool (1.8 mm off) moves a mark by at most twice that: still clear
    assert sheet_clearance_mm(border_sheet(), drawn).min() >= 0.6
    assert f"{j4[0]:.4f})" in r.program_path.read_text()
    # the seed paper's joint-4 circles: triples at one joint-1/2 pose, both elbows, and
    # joint 4 approached from both sides as session.json resolves it
    from vision_cal.dataset.session import load_session

    ses = load_session(tmp_path / "plan")
    ids = [m["id"] for m in plan["marks"]]
    z2 = plan["robot"]["joint_zero_deg"][1]
    sides, elbows = set(), set()
    for tri in r.info["joint4_triples"]:
        k = [ids.index(t) for t in tri]
        assert len({tuple(q[i]) for i in k}) == 1 and len(set(j4[k])) == 3
        sides |= {float(ses.approach4[i]) for i in k[1:]}
        elbows.add(int(np.sign(np.sin(np.radians(q[k[0], 1] + z2)))))
    assert sides == {1.0, -1.0} and elbows == {1, -1}
