"""world2 (issue 37): a print-off world written apart from the estimator and from render/.

The world's own anchors (its files follow the contract, its print has no similarity over
the markers, its pen lands where its kinematics say), and one small rendered sheet printed
0.2 mm off its layout, photographed from four places with an undeclared lens: the
calibration holds its marks and compensated targets within 0.03 mm, or its expected target
error covers the real misses and a reason names the print. The figures over ten seeds at
full size are bench/printed_off_world2.py's (docs/measured.md).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from vision_cal.dataset.calibration import load_calibration
from vision_cal.dataset.io import read_json
from vision_cal.plan.compensate import plan_targets
from vision_cal.schema import validate
from vision_cal.actions.pipeline import calibrate_dataset

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))   # world2 is not installed (world2/README.md)

from world2 import Options, make_world, session_and_truth, write_dataset  # noqa: E402
from world2.robot import Scara, approach_of  # noqa: E402

BOUND_MM = 0.03


def test_world2_writes_the_contract_and_its_own_truth():
    w = make_world(Options(seed=5))
    session, truth = session_and_truth(w, [f"p{k}.jpg" for k in range(len(w.poses))])
    validate(session, "session")
    # the print has no shift, turn or scale over the markers' corners (the contract's frame)
    c = w.layout.marker_corners()
    d = w.field(c)
    A = np.zeros((2 * len(c), 4))
    A[0::2, 0] = A[1::2, 1] = 1
    A[0::2, 2], A[0::2, 3] = c[:, 0] - c[:, 0].mean(), -(c[:, 1] - c[:, 1].mean())
    A[1::2, 2], A[1::2, 3] = c[:, 1] - c[:, 1].mean(), c[:, 0] - c[:, 0].mean()
    sim = np.linalg.lstsq(A, d.ravel(), rcond=None)[0]
    assert np.all(np.abs(sim[:2]) < 1e-9) and np.all(np.abs(sim[2:]) < 1e-12)
    assert 0.15 < truth["print"]["rms_mm"] < 0.25
    # the pen where world2's kinematics put it, the approach the contract's rule gives
    q = np.array([m["joints_deg"] for m in session["marks"]])
    s = approach_of(q, session["robot"]["home_deg"])
    given = [i for i, m in enumerate(session["marks"]) if "approach" in m]
    s[given] = [session["marks"][i]["approach"] for i in given]
    p = truth["params"]
    robot = Scara(p["L1_mm"], p["L2_mm"], *p["joint_zero_deg"], tuple(p["base_mm"]), 0.1)
    xy = np.array([truth["marks"][m["id"]] for m in session["marks"]])
    assert np.abs(robot.pen(q, s) - xy).max() < 6 * w.opt.repeat_mm


def test_a_print_off_world2_sheet_holds_or_names_the_print(tmp_path):
    opt = Options(seed=2, views=4, size_px=(1200, 900), pen_mm=2.0, plan_grid=(3, 5),
                  n_validation=3)
    folder = write_dataset(make_world(opt), tmp_path / "w2")
    run = calibrate_dataset(folder, out_dir=tmp_path / "out", jobs=1)
    doc, truth = run.document, read_json(folder / "truth.json")
    ids = [k for k, m in doc["marks"].items() if m.get("measured_mm") is not None]
    marks = np.sqrt(np.mean([np.sum((np.subtract(doc["marks"][k]["measured_mm"],
                                                 truth["marks"][k])) ** 2) for k in ids]))
    # every mark's true place as a target, from both sides, on world2's robot
    model, _ = load_calibration(tmp_path / "out" / "calibration.json")
    p = truth["params"]
    robot = Scara(p["L1_mm"], p["L2_mm"], *p["joint_zero_deg"], tuple(p["base_mm"]), 0.1)
    xy = np.array([truth["marks"][k] for k in sorted(truth["marks"])])
    miss = []
    for side in ((1, 1), (-1, -1)):
        planned = [t for t in plan_targets(model, sorted(truth["marks"]), xy, approach=side)
                   if t.status == "ok"]
        q = np.array([t.q_deg for t in planned])
        hit = robot.pen(q, np.tile(side, (len(q), 1)))
        miss += list(np.linalg.norm(hit - np.array([t.target_mm for t in planned]), axis=1))
    v = doc["verdict"]
    held = marks <= BOUND_MM and np.sqrt(np.mean(np.square(miss))) <= BOUND_MM
    named = [r for r in v["reasons"] if r.startswith("the print")]
    assert held or (v["status"] != "ready" and named
                    and np.percentile(miss, 95) <= v["expected_target_error_mm"]), (marks, v)
    # and no false cause: the robot did not change, no photo moved
    assert not [e for e in doc["effects"] if e["name"] == "drift"]
    assert not any("moved together" in r for r in v["reasons"])
