"""``plan`` does not plan targets outside the joint range the calibration's marks covered
(calibration.json ``valid_for``) where its std grows beyond what keeps its stated error (each in
PLAN.failed.csv, the rest planned, exit 3), or with ``--force`` names them in PLAN.csv and
on the console: the model is extrapolated there (one sheet's once-per-turn joint-1 error read as a gear ratio
missed by 0.16-0.21 mm outside its range, ``bench/tool_joint4.py --alone``)."""

import csv
import json
from pathlib import Path

import numpy as np

from tests.conftest import SM5
from vision_cal.commands.main import main
from vision_cal.dataset.valid_for import build as build_valid_for
from vision_cal.model.kinematics import forward

ROOT = Path(__file__).resolve().parents[2]


def test_targets_beyond_the_marks_joints_are_named(tmp_path, capsys):
    """Per target (issue 38): the targets inside are planned, each one outside goes to
    PLAN.failed.csv with why and what would cover it, exit 3 (partial); one just beyond
    the last mark, where the calibration's own expected error still holds, is
    planned; --force plans every one with the extrapolation stated."""
    assert main([str(ROOT / "fixtures" / "paper_sm5"), "--out", str(tmp_path / "c"), "-q"]) == 0
    cal = tmp_path / "c" / "calibration.json"
    doc = json.loads(cal.read_text())
    # the paper's marks: joint 1 at -20, 0, 20 deg, joint 2 at -60, 0, 60 deg
    assert doc["valid_for"]["joints_deg"] == [[-20.0, 20.0], [-60.0, 60.0]]
    # the paper's five marks (expected error 1.3 mm, known to 1 / sqrt(10)): joint 2's 120
    # deg span holds it 4.6 deg beyond, joint 1's 40 deg 1.5 deg; joint 2 at 62.5 deg (2.5
    # beyond, std 0.37 mm within the 0.67 mm limit) is planned, 100 deg (40 beyond) is not
    q = np.array([[10.0, 30.0], [-15.0, 45.0], [45.0, 30.0], [5.0, 100.0], [2.0, 62.5]])
    xy = forward(SM5, q)
    names = ["in1", "in2", "q1out", "q2out", "q2edge"]
    targets = tmp_path / "t.csv"
    targets.write_text("id,x_mm,y_mm\n" + "".join(
        f"{i},{x:.3f},{y:.3f}\n" for i, (x, y) in zip(names, xy)))
    capsys.readouterr()
    out = tmp_path / "p.csv"
    assert main(["plan", str(cal), str(targets), "-o", str(out), "-q"]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "2 outside valid_for" in err[0] and "q1out, q2out" in err[0], err
    planned = [r.split(",")[0] for r in out.read_text().splitlines()[1:]]
    assert planned == ["in1", "in2", "q2edge"], planned
    failed = {r[0]: r for r in csv.reader((tmp_path / "p.failed.csv").read_text().splitlines())}
    assert sorted(failed) == ["id", "q1out", "q2out"], failed
    why = failed["q1out"][-1]
    assert "valid_for.joints" in why and "joint 1 -20.0..20.0 deg" in why, why
    assert "--joint" in why and "std" in why, why
    # with --force: written, the extrapolation stated in the file and on the console
    assert main(["plan", str(cal), str(targets), "-o", str(out), "-q", "--force"]) == 0
    err = [ln for ln in capsys.readouterr().err.splitlines() if "outside the joints" in ln]
    assert len(err) == 1 and "q1out, q2out" in err[0] and "--force" in err[0], err
    rows = {r.split(",")[0]: r.split(",")[-1] for r in out.read_text().splitlines()[1:]}
    assert out.read_text().splitlines()[0].endswith(",outside_valid_for")
    assert rows == {"in1": "", "in2": "", "q1out": "joints", "q2out": "joints",
                    "q2edge": ""}, rows
    # a mark left out as unreliable does not widen the range
    doc["marks"]["j1p"]["status"] = "unreliable"
    assert build_valid_for(doc)["joints_deg"][0] == [-20.0, 0.0]


def test_how_far_beyond_follows_the_calibrations_own_expected_error():
    """valid_for.check: up to ``beyond_deg`` past the covered range an item is inside while
    its std is within the limit; further, or with a larger std, outside; without the
    calibration's figures, the slack alone (a hard 1 deg, as before)."""
    from vision_cal.dataset.valid_for import check, per_item

    vf = {"joints_deg": [[-20.0, 20.0], [-60.0, 60.0]]}
    q = [[22.5, 0.0], [22.5, 0.0], [25.0, 0.0], [0.0, 0.0]]
    out = check(vf, ids=["a", "b", "c", "d"], joints_deg=q, std_mm=[0.010, 0.013, 0.010, 0.5],
                std_limit_mm=0.012, beyond_deg=(3.0, 3.0))
    assert [o.ids for o in out] == [("b", "c")]   # d is inside the range: its std not asked
    whole, items = per_item(out)
    assert not whole and list(items) == ["b", "c"] and "std 0.0130 mm" in items["b"][0]
    assert check(vf, ids=["a"], joints_deg=[[22.5, 0.0]])[0].ids == ("a",)
    assert check(vf, ids=["a"], joints_deg=[[20.9, 0.0]]) == []
