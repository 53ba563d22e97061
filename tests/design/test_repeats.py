"""Repeatability measured, not assumed (issue 17): the designed plan returns to a few of its
poses (``repeat_of``), and the calibration's verdict uses the repeatability those pairs
measure."""

import json

import numpy as np
import pytest

from tests.design.conftest import border_sheet
from vision_cal.design.stage import DESIGN_REPEATS
from vision_cal.errors import VisionCalError
from vision_cal.plan.calibration_plan import REPEAT_GAP, REPEAT_SHIFT_MM, sheet_clearance_mm
from vision_cal.world.truth_model import TrueRobot

TRUTH = TrueRobot.from_json(
    {"L1_mm": 344.05, "L2_mm": 259.87, "joint_zero_deg": [-2.57, -8.13],
     "base_mm": [-420.0, -230.0]}, [{"name": "joint_backlash", "joint": 2, "deg": 0.1}])


def test_designed_plan_draws_marks_twice(informative_dir):
    s = json.loads((informative_dir / "session.json").read_text())
    marks = s["marks"]
    ids = [m["id"] for m in marks]
    reps = [m for m in marks if "repeat_of" in m]
    assert len(reps) == DESIGN_REPEATS == s["design"]["n_repeats"]
    by_id = {m["id"]: m for m in marks}
    twins = {m["repeat_of"] for m in reps}
    assert len(twins) == len(reps)          # each twin returned to once
    for m in reps:
        t = by_id[m["repeat_of"]]
        assert t["role"] == m["role"] == "calibration" and "repeat_of" not in t
        assert m["approach"] == t["approach"]       # from the same side
        # drawn after its twin, the arm having left for other marks in between
        assert ids.index(m["id"]) - ids.index(t["id"]) >= REPEAT_GAP
        # on the true robot: a few mm from the twin, apart from it and on free paper
        q = np.array([m["joints_deg"], t["joints_deg"]])
        xy = TRUTH.pen_mm(q, np.array([m["approach"], t["approach"]]))
        assert abs(np.linalg.norm(xy[0] - xy[1]) - REPEAT_SHIFT_MM) < 0.5
        assert sheet_clearance_mm(border_sheet(), xy[:1])[0] >= 0.6 + 3.0


def test_calibration_reports_the_measured_repeatability(tmp_path, informative_dir):
    """The plan drawn by a robot whose repeatability is 0.02 mm (per axis, one std), marks
    measured to 0.005 mm: the verdict's floor uses the pairs' figure, not the robot file's
    0.01 mm; within 4 of its std, (sigma^2 + r^2) / (2 r sqrt(n)) = 3.8 um for 8 pairs."""
    from vision_cal.estimate.verdict import judge
    from vision_cal.actions.pipeline import calibrate_dataset

    r_true, sig = 0.02, 0.005
    rng = np.random.default_rng(41)
    s = json.loads((informative_dir / "session.json").read_text())
    q = np.array([m["joints_deg"] for m in s["marks"]])
    a = np.array([m["approach"] for m in s["marks"]])
    xy = TRUTH.pen_mm(q, a) + rng.normal(0, np.hypot(r_true, sig), q.shape)
    for m, p in zip(s["marks"], xy):
        m["measured_mm"] = p.tolist()
    (tmp_path / "session.json").write_text(json.dumps(s))
    doc = calibrate_dataset(tmp_path, out_dir=tmp_path / "out").document
    reps = {k: m["repeat_of"] for k, m in doc["marks"].items() if "repeat_of" in m}
    assert len(reps) == DESIGN_REPEATS
    for m in doc["marks"].values():   # what a photographed mark carries
        m["sigma_mm"] = sig
    v = judge(doc, repeatability_mm=0.01)
    assert v.repeatability_source.startswith(f"{DESIGN_REPEATS} pairs")
    assert abs(v.repeatability_mm - r_true) < 4 * (sig**2 + r_true**2) / (
        2 * r_true * np.sqrt(DESIGN_REPEATS))


def test_a_repeat_must_name_another_mark_from_the_same_side(tmp_path, informative_dir):
    from vision_cal.dataset.session import load_session

    s = json.loads((informative_dir / "session.json").read_text())
    rep = next(m for m in s["marks"] if "repeat_of" in m)
    for bad, words in (("zz", "not another mark"), (rep["id"], "not another mark")):
        rep["repeat_of"] = bad
        (tmp_path / "session.json").write_text(json.dumps(s))
        with pytest.raises(VisionCalError, match=words) as e:
            load_session(tmp_path)
        assert "repeat_of" in str(e.value)
