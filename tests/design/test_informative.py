"""From the pilot's calibration to the informative plan, on the true robot."""

import json

import numpy as np
import pytest

from tests.design.conftest import ROBOT, border_sheet
from vision_cal.design.stage import DESIGN_REPEATS
from vision_cal.plan.calibration_plan import sheet_clearance_mm
from vision_cal.world.truth_model import TrueRobot

TRUTH = TrueRobot.from_json(
    {"L1_mm": 344.05, "L2_mm": 259.87, "joint_zero_deg": [-2.57, -8.13],
     "base_mm": [-420.0, -230.0]}, [{"name": "joint_backlash", "joint": 2, "deg": 0.1}])


@pytest.fixture(scope="module")
def informative(tmp_path_factory, pilot_dir, sheet_json):
    """The pilot drawn by the true robot, measured to 0.02 mm, calibrated; then designed."""
    from vision_cal.design.stage import design_stage
    from vision_cal.actions.pipeline import calibrate_dataset

    rng = np.random.default_rng(3)
    s = json.loads((pilot_dir / "session.json").read_text())
    q = np.array([m["joints_deg"] for m in s["marks"]])
    a = np.array([m["approach"] for m in s["marks"]])
    xy = TRUTH.pen_mm(q, a) + rng.normal(0, 0.02, q.shape)
    for m, p in zip(s["marks"], xy):
        m["measured_mm"] = p.tolist()
    d = tmp_path_factory.mktemp("pilot_measured")
    (d / "session.json").write_text(json.dumps(s))
    cal = calibrate_dataset(d, out_dir=d / "out").out_path
    out = tmp_path_factory.mktemp("plan")
    r = design_stage(ROBOT, sheet_json, out, pilot=cal, program="csv")
    return r, json.loads((out / "session.json").read_text()), xy


def test_informative_marks_land_on_free_paper_on_the_true_robot(informative):
    """Catches: planning with the nominal robot (its marks land tens of mm away, on
    markers and off the paper) instead of the pilot's model."""
    r, s, _ = informative
    q = np.array([m["joints_deg"] for m in s["marks"]])
    a = np.array([m["approach"] for m in s["marks"]])
    xy = TRUTH.pen_mm(q, a)
    assert sheet_clearance_mm(border_sheet(), xy).min() >= 0.6 + 3.0
    assert r.info["safety_mm"] >= 5.0


def test_informative_marks_keep_clear_of_the_pilots_marks(informative):
    """Drawn on the same sheet, unmoved: no mark may touch or crowd a pilot mark (the
    photos would confuse them). Catches: the pilot's marks not treated as obstacles."""
    r, s, pilot_xy = informative
    q = np.array([m["joints_deg"] for m in s["marks"]])
    xy = TRUTH.pen_mm(q, np.array([m["approach"] for m in s["marks"]]))
    d = np.linalg.norm(xy[:, None] - pilot_xy[None], axis=2)
    assert d.min() >= 1.2 + r.info["safety_mm"] - 1.0


def test_informative_plan_has_both_elbows_sides_and_roles(informative):
    r, s, _ = informative
    marks = s["marks"]
    n_rep = DESIGN_REPEATS   # calibration marks drawn twice (tests/design/test_repeats.py)
    assert len(marks) == 38 + n_rep and "images" not in s
    assert s["design"]["stage"] == "informative"
    roles = [m["role"] for m in marks]
    assert roles.count("calibration") == 30 + n_rep and roles.count("validation") == 8
    a = np.array([m["approach"] for m in marks])
    assert set(a[:, 0]) == {1, -1} and set(a[:, 1]) == {1, -1}
    q = np.array([m["joints_deg"] for m in marks])
    z2 = s["robot"]["joint_zero_deg"][1]
    assert set(np.sign(np.sin(np.radians(q[:, 1] + z2)))) == {1.0, -1.0}
    # the session's robot is the pilot's model, within a millimetre of the truth
    assert abs(s["robot"]["base_mm"][0] - TRUTH.base_mm[0]) < 1.0
    assert r.program_path.name == "program_points.csv"


def test_pilot_marks_are_obstacles_of_the_design_sheet():
    """Catches: a pilot mark not seen by the clearance the informative design uses."""
    from vision_cal.design.stage import with_pilot_marks

    sheet = border_sheet()
    doc = {"marks": {"c00": {"measured_mm": [10.0, 20.0]}, "c01": {"measured_mm": [-50.0, 0.0]}}}
    s2 = with_pilot_marks(sheet, doc, 1.2)
    assert len(s2.markers) == len(sheet.markers) + 2
    c = sheet_clearance_mm(s2, [[10.0, 20.0], [-50.0, 5.0], [100.0, 100.0]])
    assert c[0] == 0.0 and np.isclose(c[1], 5.0 - 0.6)
    assert np.isclose(c[2], sheet_clearance_mm(sheet, [[100.0, 100.0]])[0])
