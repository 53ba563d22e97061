"""Marks from other instruments (issue 32): a tracker-style CSV calibrates as the same marks
given as ``measured_mm`` in a session (the same figures), with the noise floor from the
stated accuracy. The marks come from the world's own robot (kinematic: no photos)."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest
import yaml

from tests.conftest import ROOT, SM5, random_plan
from vision_cal.commands.main import main
from vision_cal.dataset.marks_csv import session_from_marks_csv
from vision_cal.errors import VisionCalError
from vision_cal.actions.pipeline import calibrate_dataset
from vision_cal.world.truth_model import TrueRobot

N, SIGMA = 40, 0.02            # marks; the instrument's accuracy, one std per axis (mm)
BACKLASH = {"name": "joint_backlash", "joint": 2, "deg": 0.08}
#: the tracker's frame: turned 30 deg and moved from the sheet frame the robot is given in
TURN_DEG, SHIFT_MM = 30.0, np.array([1200.0, -350.0])
FIXTURE = ROOT / "fixtures" / "tracker_example"


def tracker_world(seed: int = 32, n: int = N, sigma: float = SIGMA):
    """(q (n, 2), approach (n, 2), xy (n, 2) in the tracker's frame, truth, robot block):
    the true SM5 with joint-2 backlash draws ``n`` marks; a tracker measures each with
    ``sigma`` per axis, in its own frame (a rigid turn and shift of the sheet frame)."""
    rng = np.random.default_rng(seed)
    q, s = random_plan(n, rng)
    truth = TrueRobot.from_json(SM5.to_json(), [BACKLASH])
    xy = truth.pen_mm(q, s) + rng.normal(0.0, sigma, (n, 2))
    a = math.radians(TURN_DEG)
    R = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    xy_t = xy @ R.T + SHIFT_MM
    base_t = R @ np.array([SM5.base_x_mm, SM5.base_y_mm]) + SHIFT_MM
    robot = {"name": "SM5 (tracker example)", "L1_mm": 350.0, "L2_mm": 260.0,
             "joint_zero_deg": [round(TURN_DEG, 1), 0.0],
             "base_mm": [round(float(base_t[0]) + 20.0, 1), round(float(base_t[1]) - 15.0, 1)],
             "home_deg": [0.0, 0.0]}
    return q, s, xy_t, truth, robot


def write_csv(path, q, s, xy) -> None:
    rows = ["id,q1_deg,q2_deg,x_mm,y_mm,approach1,approach2"]
    rows += [f"m{i:02d},{q[i, 0]:.4f},{q[i, 1]:.4f},{xy[i, 0]:.4f},{xy[i, 1]:.4f},"
             f"{int(s[i, 0])},{int(s[i, 1])}" for i in range(len(q))]
    path.write_text("\n".join(rows) + "\n")


def write_session(folder, q, s, xy, robot, sigma) -> None:
    """The same marks as a session.json whose marks all carry measured_mm (4 decimals, as
    the CSV) and the stated accuracy."""
    folder.mkdir(parents=True, exist_ok=True)
    block = {k: v for k, v in robot.items() if k != "name"}
    marks = [{"id": f"m{i:02d}", "joints_deg": [round(q[i, 0], 4), round(q[i, 1], 4)],
              "approach": [int(s[i, 0]), int(s[i, 1])],
              "measured_mm": [round(xy[i, 0], 4), round(xy[i, 1], 4)],
              "measured_sigma_mm": sigma} for i in range(len(q))]
    (folder / "session.json").write_text(json.dumps(
        {"format": "vision-cal/1", "robot": block, "marks": marks, "images": []}))


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    """The CSV and the measured_mm session of the same marks, each calibrated."""
    tmp = tmp_path_factory.mktemp("tracker")
    q, s, xy, truth, robot = tracker_world()
    write_csv(tmp / "marks.csv", q, s, xy)
    (tmp / "robot.yaml").write_text(yaml.safe_dump(robot))
    write_session(tmp / "session", q, s, xy, robot, SIGMA)
    assert main(["calibrate", str(tmp / "marks.csv"), "--robot", str(tmp / "robot.yaml"),
                 "--sigma-mm", str(SIGMA), "--out", str(tmp / "out_csv"), "-q"]) == 0
    run = calibrate_dataset(tmp / "session", out_dir=tmp / "out_session")
    csv_doc = json.loads((tmp / "out_csv" / "calibration.json").read_text())
    return csv_doc, run.document, truth


def test_a_tracker_csv_calibrates_with_the_figures_of_the_same_marks_as_measured_mm(both):
    """The same parameters, effects, residuals, std and verdict, to the last digit."""
    a, b, _ = both
    for key in ("params", "std", "residual_rms_mm", "validation_rms_mm", "verdict"):
        assert a[key] == b[key], key
    assert [(e["name"], e.get("joint"), e.get("deg")) for e in a["effects"]] == \
        [(e["name"], e.get("joint"), e.get("deg")) for e in b["effects"]]
    assert a["marks"] == b["marks"]


def test_the_floor_is_the_stated_accuracy_and_the_backlash_is_found(both):
    """--sigma-mm is each mark's noise: the floor is there and explains the residual (the
    instrument's noise is what the world added); the joint-2 backlash found within 4 std;
    the model is frame-free (the tracker's frame turned 30 deg and moved 1.2 m)."""
    a, _, _ = both
    assert all(m["sigma_mm"] == SIGMA for m in a["marks"].values())
    floor = a["verdict"]["floor"]
    assert floor is not None and floor["residual_over_floor"] < 1.5
    assert not any("noise floor" in r for r in a["verdict"]["reasons"])
    bl = [e for e in a["effects"] if e["name"] == "joint_backlash" and e["joint"] == 2]
    assert bl and abs(bl[0]["deg"] - BACKLASH["deg"]) < 4 * bl[0]["std"]
    assert abs(a["params"]["L1_mm"] - SM5.L1_mm) < 4 * a["std"]["L1_mm"]
    assert abs(a["params"]["joint_zero_deg"][0] - (SM5.z1_deg + TURN_DEG)) < \
        4 * a["std"]["joint_zero_deg"][0] + 1e-9


def test_without_a_stated_accuracy_the_verdict_says_there_is_no_floor(tmp_path):
    q, s, xy, _, robot = tracker_world(n=20)
    write_csv(tmp_path / "m.csv", q, s, xy)
    (tmp_path / "r.yaml").write_text(yaml.safe_dump(robot))
    session = session_from_marks_csv(tmp_path / "m.csv", tmp_path / "r.yaml")
    assert all(m.measured_sigma_mm is None for m in session.marks)
    doc = calibrate_dataset(session, out_dir=tmp_path / "o").document
    assert doc["verdict"]["floor"] is None if "floor" in doc["verdict"] else True
    assert any("no measurement noise" in r for r in doc["verdict"]["reasons"])


@pytest.mark.parametrize("row,args,field", [
    ("m00,10,20,100,200,1,0", ["--sigma-mm", "0.02"], "line 2: approach1, approach2"),
    ("m00,10,20,1OO,200,1,1", [], "line 2: x_mm"),
    ("m00,10,20,100,200,1,1", ["--sigma-mm", "-1"], "--sigma-mm"),
])
def test_a_bad_marks_csv_is_one_line_naming_the_field(tmp_path, row, args, field):
    (tmp_path / "m.csv").write_text("id,q1_deg,q2_deg,x_mm,y_mm,approach1,approach2\n"
                                    + row + "\n")
    shutil.copy(FIXTURE / "robot.yaml", tmp_path / "r.yaml")
    sigma = float(args[1]) if args else None
    with pytest.raises(VisionCalError) as e:
        session_from_marks_csv(tmp_path / "m.csv", tmp_path / "r.yaml", sigma_mm=sigma)
    assert e.value.field == field


def test_a_marks_csv_without_its_robot_file_exits_2_naming_robot(tmp_path, capsys):
    shutil.copy(FIXTURE / "marks.csv", tmp_path / "m.csv")
    assert main(["calibrate", str(tmp_path / "m.csv"), "--out", str(tmp_path / "o")]) == 2
    assert "--robot" in capsys.readouterr().err


def test_the_fixture_is_the_world_it_says():
    """fixtures/tracker_example/ is tracker_world(seed 32) as written (its README says how
    it was made)."""
    q, s, xy, _, robot = tracker_world()
    session = session_from_marks_csv(FIXTURE / "marks.csv", FIXTURE / "robot.yaml",
                                     sigma_mm=SIGMA)
    got = np.array([m.measured_mm for m in session.marks])
    assert np.allclose(got, xy, atol=6e-5) and len(session.marks) == N
    assert yaml.safe_load((FIXTURE / "robot.yaml").read_text()) == robot


def test_a_marks_csv_in_metres_or_a_pdf_is_named_as_what_it_is(tmp_path, capsys):
    """The wrong kind of input: marks written in metres are refused naming the CSV (not a
    session.json the user never wrote) and the likely unit; a PDF saved as .csv is called a
    PDF, not taken for the sheet's; nothing is written, the inputs stay as they were."""
    fx = ROOT / "fixtures" / "tracker_example"
    rows = (fx / "marks.csv").read_text().splitlines()
    head = rows[0].split(",")
    ix, iy = head.index("x_mm"), head.index("y_mm")
    out = [rows[0]]
    for r in rows[1:]:
        c = r.split(",")
        c[ix], c[iy] = str(float(c[ix]) / 1000), str(float(c[iy]) / 1000)
        out.append(",".join(c))
    (tmp_path / "m.csv").write_text("\n".join(out) + "\n")
    (tmp_path / "x.csv").write_bytes(b"%PDF-1.4\n\xe2\xe3\xcf\xd3 binary")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert main(["calibrate", str(tmp_path / "m.csv"), "--robot", str(fx / "robot.yaml"),
                 "--out", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "m.csv: marks:" in err and "metres" in err and "session.json" not in err
    assert main(["calibrate", str(tmp_path / "x.csv"), "--robot", str(fx / "robot.yaml"),
                 "--out", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "is a PDF" in err and "sheet" not in err
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_a_marks_csv_beyond_the_bound_is_one_line_naming_it(tmp_path, monkeypatch):
    """More marks than marks_csv.MAX_MARKS (100,000: docs/format.md) are refused naming the
    bound, before any fit (here the bound lowered to 3 for a 4-row file)."""
    import vision_cal.dataset.marks_csv as marks_csv

    rows = (FIXTURE / "marks.csv").read_text().splitlines()[:5]
    (tmp_path / "m.csv").write_text("\n".join(rows) + "\n")
    monkeypatch.setattr(marks_csv, "MAX_MARKS", 3)
    with pytest.raises(VisionCalError) as e:
        session_from_marks_csv(tmp_path / "m.csv", FIXTURE / "robot.yaml")
    assert "at most 3" in str(e.value) and e.value.file == str(tmp_path / "m.csv")


def test_a_long_calibration_says_when_each_stage_starts_and_ends(tmp_path, monkeypatch, capsys):
    """From pipeline.PROGRESS_MARKS marks (2,000; lowered to the fixture's 40 here) the fit +
    diagnosis and the writing of calibration.json each print a progress line as they start
    and as they end; below it, none."""
    import vision_cal.actions.pipeline as pipeline

    argv = ["calibrate", str(FIXTURE / "marks.csv"), "--robot", str(FIXTURE / "robot.yaml"),
            "--sigma-mm", str(SIGMA), "--out", str(tmp_path / "o")]
    monkeypatch.setattr(pipeline, "PROGRESS_MARKS", N)
    assert main(argv) == 0
    err = [ln for ln in capsys.readouterr().err.splitlines() if "progress:" in ln]
    for stage in ("fit + diagnosis", "calibration.json"):
        assert f"vision-cal: progress: {stage}: {N} marks ..." in err
        assert any(ln.startswith(f"vision-cal: progress: {stage}: {N}/{N} marks in ")
                   for ln in err), err
    monkeypatch.setattr(pipeline, "PROGRESS_MARKS", N + 1)
    assert main(argv) == 0
    assert "progress: fit" not in capsys.readouterr().err
