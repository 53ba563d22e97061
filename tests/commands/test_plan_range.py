"""``plan`` refuses targets outside the joint range the calibration's marks covered
(calibration.json ``valid_for``), or with ``--force`` names them in PLAN.csv and on the
console: the model is extrapolated there (one sheet's once-per-turn joint-1 error read as a gear ratio
missed by 0.16-0.21 mm outside its range, ``bench/tool_joint4.py --alone``)."""

import json
from pathlib import Path

import numpy as np

from tests.conftest import SM5
from vision_cal.commands.main import main
from vision_cal.dataset.calibration import joints_covered_deg
from vision_cal.model.kinematics import forward

ROOT = Path(__file__).resolve().parents[2]


def test_targets_beyond_the_marks_joints_are_named(tmp_path, capsys):
    assert main([str(ROOT / "fixtures" / "paper_sm5"), "--out", str(tmp_path / "c"), "-q"]) == 0
    cal = tmp_path / "c" / "calibration.json"
    doc = json.loads(cal.read_text())
    # the paper's marks: joint 1 at -20, 0, 20 deg, joint 2 at -60, 0, 60 deg
    assert joints_covered_deg(doc) == [(-20.0, 20.0), (-60.0, 60.0)]
    q = np.array([[10.0, 30.0], [-15.0, 45.0], [45.0, 30.0], [5.0, 100.0]])
    xy = forward(SM5, q)
    targets = tmp_path / "t.csv"
    targets.write_text("id,x_mm,y_mm\n" + "".join(
        f"{i},{x:.3f},{y:.3f}\n" for i, (x, y) in zip(["in1", "in2", "q1out", "q2out"], xy)))
    capsys.readouterr()
    out = tmp_path / "p.csv"
    # refused (exit 2, one line: the reason and what would cover it), nothing written
    assert main(["plan", str(cal), str(targets), "-o", str(out), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "valid_for.joints" in err[0], err
    assert "2 of 4" in err[0] and "q1out, q2out" in err[0], err[0]
    assert "joint 1 -20.0..20.0 deg" in err[0] and "--joint" in err[0] and "--force" in err[0]
    assert not out.exists()
    # with --force: written, the extrapolation stated in the file and on the console
    assert main(["plan", str(cal), str(targets), "-o", str(out), "-q", "--force"]) == 0
    err = [ln for ln in capsys.readouterr().err.splitlines() if "outside the joints" in ln]
    assert len(err) == 1 and "q1out, q2out" in err[0] and "--force" in err[0], err
    rows = {r.split(",")[0]: r.split(",")[-1] for r in out.read_text().splitlines()[1:]}
    assert out.read_text().splitlines()[0].endswith(",outside_valid_for")
    assert rows == {"in1": "", "in2": "", "q1out": "joints", "q2out": "joints"}, rows
    # a mark left out as unreliable does not widen the range
    doc["marks"]["j1p"]["status"] = "unreliable"
    assert joints_covered_deg(doc)[0] == (-20.0, 0.0)
