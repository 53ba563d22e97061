"""design: joint-4 turns that keep each planned mark on its sheet point."""

import numpy as np

from vision_cal.design.joint4 import turn_joint4
from vision_cal.model.kinematics import ScaraParams, forward
from vision_cal.plan.calibration_plan import PlannedMark
from vision_cal.plan.orient import folded_params
from vision_cal.world.truth_model import TrueRobot

TRUE = {"L1_mm": 344.05, "L2_mm": 259.87, "joint_zero_deg": [-2.57, -8.13],
        "base_mm": [-424.26, -230.35], "tool_mm": [21.0, -7.0]}


def test_turned_marks_stay_on_their_points():
    truth = TrueRobot.from_json(TRUE)
    # what a pilot at j4 = 0 calibrates: the tool folded into link 2
    folded = folded_params(ScaraParams(344.05, 259.87, -2.57, -8.13, -424.26, -230.35),
                           TRUE["tool_mm"], 0.0)
    plan = [PlannedMark(f"c{i}", (a, b), approach=(1, -1), via_deg=((a - 3, b + 3),))
            for i, (a, b) in enumerate([(20, -60), (45, -90), (70, -40), (30, -110)])]
    turned, j4 = turn_joint4(plan, folded, TRUE["tool_mm"])
    assert len(set(j4.values())) == 4          # four different tool directions
    q = np.array([[*m.joints_deg, j4[m.id]] for m in turned])
    np.testing.assert_allclose(truth.pen_mm(q), forward(folded, [m.joints_deg for m in plan]),
                               atol=1e-6)
    assert all(m.approach == (1, -1) for m in turned)
    # the via points keep each joint's approach side
    for m in turned:
        assert np.all(np.sign(np.subtract(m.joints_deg, m.via_deg[0])) == (1, -1))


def test_circle_triples_paper_style_on_free_paper(tmp_path):
    """Joint-4 circles as in the seed paper: three marks at one joint-1/joint-2 pose, joint 4
    alone turned 120 deg between them; both elbows, joint 4 approached from both sides
    (by the format's rule over the drawn order), every mark clear of the markers and of the
    sheet's printed content (axes, arrows, text)."""
    import json

    from vision_cal.dataset.session import load_sheet_file
    from vision_cal.design.joint4 import circle_triples, joint4_vias
    from vision_cal.design.stage import drawable_sheet, with_printed_content
    from vision_cal.model.robot import RobotModel, Tool
    from vision_cal.model.motion import approach_signs
    from vision_cal.plan.calibration_plan import sheet_clearance_mm
    from vision_cal.plan.orient import unfold_params
    from vision_cal.sheet import make_layout, write_sheet

    write_sheet(make_layout(size="A3"), tmp_path)
    raw = json.loads((tmp_path / "sheet.json").read_text())
    sheet = with_printed_content(drawable_sheet(load_sheet_file(tmp_path / "sheet.json"), raw))
    folded = ScaraParams(344.05, 259.87, -2.57, -8.13, -100.0, -330.0)
    tool = (21.0, -7.0)
    marks, j4 = circle_triples(folded, tool, sheet, rng=3, clearance_mm=4.0)
    assert len(marks) == 12
    elbows, sides = set(), set()
    unfolded = unfold_params(folded, tool)
    q4 = np.array([j4[m.id] for m in marks])
    s4 = approach_signs(np.column_stack([q4, q4]))[:, 0]
    for k in range(4):
        tri = marks[3 * k:3 * k + 3]
        assert len({m.joints_deg for m in tri}) == 1 and len({m.approach for m in tri}) == 1
        a = q4[3 * k:3 * k + 3]
        np.testing.assert_allclose(np.abs(np.diff(a)), 120.0)
        sides |= set(s4[3 * k + 1:3 * k + 3])          # joint 4 alone moves within a triple
        elbows.add(int(np.sign(np.sin(np.radians(tri[0].joints_deg[1] + unfolded.z2_deg)))))
    assert sides == {1.0, -1.0} and elbows == {1, -1}
    # every mark (nominal model with the rough tool) on free paper, print included
    model = RobotModel(unfolded, (Tool(tool_mm=tool),))
    xy = model.predict([[*m.joints_deg, j4[m.id]] for m in marks])
    assert sheet_clearance_mm(sheet, xy).min() >= 4.0
    # the program's joint-4 via points come from the side the session's rule resolves
    vias = joint4_vias(marks, j4, overshoot_deg=3.0)
    for m, s in zip(marks, s4):
        assert np.sign(vias[m.id][0] - vias[m.id][1]) == s
