"""What a calibration was calibrated for (issue 29 section 2): calibration.json ``valid_for``
(vision_cal/dataset/valid_for.py), the verdict judged against it, and every consumer that
refuses a request outside it (exit 2, one line: the reason and what would cover it) or,
with ``--force``, writes it with the extrapolation stated in the file and on the console.

The seed paper's five marks (fixtures/paper_sm5: both approach sides on both joints, joint 1
-20..20 deg, joint 2 -60..60 deg) are calibrated once; each case edits what the file says it
saw (one approach side, a tool never turned), as a pilot's would."""

from __future__ import annotations

import copy
import csv
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from vision_cal.commands.main import main
from vision_cal.dataset import valid_for as vf_mod
from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.dataset.trust import require_usable_pilot
from vision_cal.estimate.verdict import judge

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def paper(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("paper")
    assert main([str(ROOT / "fixtures" / "paper_sm5"), "--out", str(out), "-q"]) == 0
    return json.loads((out / "calibration.json").read_text())


def _one_side(doc: dict, joint: int = 2) -> dict:
    """The document as a pilot's: every mark reached joint ``joint`` from +1; valid_for
    rebuilt from its marks (the pipeline's builder)."""
    d = copy.deepcopy(doc)
    for m in d["marks"].values():
        m["approach"][joint - 1] = 1
    d["valid_for"] = vf_mod.build(d)
    return d


def _write(tmp_path, doc, name="cal.json") -> Path:
    p = tmp_path / name
    p.write_text(json.dumps(doc))
    return p


def _inside_targets(tmp_path, doc, theta=None) -> Path:
    """Two targets where the marks are (inside the joints they covered)."""
    marks = list(doc["marks"].values())[:2]
    head = "id,x_mm,y_mm" + (",theta_deg" if theta is not None else "")
    rows = [f"t{k},{m['measured_mm'][0]},{m['measured_mm'][1]}"
            + (f",{theta[k]}" if theta is not None else "") for k, m in enumerate(marks)]
    t = tmp_path / "targets.csv"
    t.write_text("\n".join([head, *rows]) + "\n")
    return t


def _err_lines(capsys) -> list[str]:
    return [ln for ln in capsys.readouterr().err.strip().splitlines() if ln]


# --------------------------------------------------------------------------- the block

def test_the_block_says_what_the_marks_covered(paper):
    vf = paper["valid_for"]     # written by the pipeline
    assert vf["joints_deg"] == [[-20.0, 20.0], [-60.0, 60.0]]
    assert vf["approach_sides"] == {"1": [-1, 1], "2": [-1, 1]}
    assert vf["heights_mm"] == [0.0, 0.0] and vf["not_identified"] == []
    one = _one_side(paper)["valid_for"]
    assert one["approach_sides"]["2"] == [1]
    (d,) = one["not_identified"]
    assert d["label"] == "joint_backlash(joint 2)" and "approach -1 on joint 2" in d["excited_by"]


def test_a_tool_never_turned_is_not_identified(paper):
    d = copy.deepcopy(paper)
    d["tool"] = {"identified": False, "j4_deg": 0.0, "tool_mm_nominal": [25.0, 0.0]}
    vf = vf_mod.build(d)
    assert vf["tool_identified"] is False and vf["joint4_deg"] == [0.0]
    assert [x["label"] for x in vf["not_identified"]] == ["tool_mm"]


# --------------------------------------------------------------------------- the verdict

def test_a_pilot_that_cannot_identify_backlash_is_never_ready(paper):
    """The known case: a pilot said "ready ... 0.027 mm" while printing "not identifiable by
    this plan: joint_backlash(joint 2)". Judged against valid_for it is "check", naming the
    effect, what excites it and what to draw; inside valid_for it is ready, so design
    --pilot still takes it."""
    d = _one_side(paper)
    d["identifiability"]["not_identifiable"] = [
        {"label": "joint_backlash(joint 2)", "reason": "z2 ~ backlash", "fix": "both sides"}]
    d.pop("verdict", None)
    v = judge(d, stage="pilot")
    assert v.status == "check", v
    text = " ".join(v.reasons)
    assert "joint_backlash(joint 2)" in text and "approach -1 on joint 2" in text
    assert "both directions" in text
    assert v.within_valid_for is not None
    # the same document with both sides seen has no such reason
    assert not any("not identified" in r for r in judge(paper, stage="pilot").reasons)
    # the reasons valid_for adds are said as such (reason_codes): design --pilot takes the
    # pilot, saying the informative plan is designed to fix them
    codes = dict(zip(v.reasons, v.reason_codes))
    assert [codes[r] for r in v.reasons if "not identified" in r] == ["not_identified"]
    note = require_usable_pilot(CalibrationResult.from_json({"verdict": v.to_json()}),
                                "pilot.json")
    assert "effects a pilot cannot identify" in " ".join(note), note


# --------------------------------------------------------------------------- plan

def test_plan_refuses_the_approach_side_never_seen(paper, tmp_path, capsys):
    cal = _write(tmp_path, _one_side(paper))
    t = _inside_targets(tmp_path, paper)
    out = tmp_path / "p.csv"
    # the side it saw: planned as before
    assert main(["plan", str(cal), str(t), "-o", str(out), "-q"]) == 0
    assert "outside_valid_for" not in out.read_text()
    out.unlink()
    capsys.readouterr()
    # every target outside: none planned (exit 1), each in the report with why and what
    # would cover it
    assert main(["plan", str(cal), str(t), "-o", str(out), "-q", "--approach", "-1", "-1"]) == 1
    (line,) = _err_lines(capsys)
    assert "2 outside valid_for" in line and "p.failed.csv" in line, line
    why = (tmp_path / "p.failed.csv").read_text()
    assert "valid_for.approach2" in why and "joint 2" in why and "vision-cal design" in why
    assert "outside_valid_for" not in (out.read_text() if out.exists() else "")
    assert main(["plan", str(cal), str(t), "-o", str(out), "-q", "--approach", "-1", "-1",
                 "--force"]) == 0
    err = _err_lines(capsys)
    assert any("approach joint 2" in ln and "--force" in ln for ln in err), err
    rows = out.read_text().splitlines()
    assert rows[0].endswith("outside_valid_for") and all(r.endswith("approach2")
                                                         for r in rows[1:]), rows


def test_plan_refuses_orientations_with_a_tool_never_turned(paper, tmp_path, capsys):
    """The tool folded into L2 and z2: targets at theta 0, 90, 180 would each turn joint 4
    and move a 25 mm-offset pen by about 35 mm; refused naming the tool."""
    d = copy.deepcopy(paper)
    d["tool"] = {"identified": False, "j4_deg": 0.0, "tool_mm_nominal": [25.0, 0.0]}
    d["valid_for"] = vf_mod.build(d)
    cal = _write(tmp_path, d)
    t = _inside_targets(tmp_path, paper, theta=[0.0, 90.0])
    out = tmp_path / "p.csv"
    assert main(["plan", str(cal), str(t), "-o", str(out), "-q"]) == 1
    (line,) = _err_lines(capsys)
    assert "outside valid_for" in line, line
    why = (tmp_path / "p.failed.csv").read_text()
    assert "valid_for.joint4" in why and "tool" in why and "tool_mm" in why, why
    assert main(["plan", str(cal), str(t), "-o", str(out), "-q", "--force"]) == 0
    assert "joint4" in out.read_text()


# --------------------------------------------------------------------------- locate

def _with_camera(doc: dict, height_mm: float, intrinsics: str = "estimated",
                 over_mm=(400.0, 0.0)) -> dict:
    """The document with a still camera looking straight down from ``height_mm`` over the
    robot-frame point ``over_mm`` (the robot frame is the sheet's here: z1 0, base 0)."""
    d = copy.deepcopy(doc)
    T = np.diag([1.0, -1.0, -1.0, 1.0])            # looking straight down
    T[:3, 3] = [*over_mm, height_mm]
    d["cameras"] = [{"images": ["a.png"], "size_px": [1200, 900],
                     "K": [[1000.0, 0, 599.5], [0, 1000.0, 449.5], [0, 0, 1]],
                     "dist": [0.0] * 5, "T_robot_camera": T.tolist(), "intrinsics": intrinsics,
                     "robot_to_sheet": {"z1_deg": 0.0, "base_mm": [0.0, 0.0],
                                        "sheet_matrix": np.eye(2).tolist()}}]
    d["valid_for"] = vf_mod.build(d)
    return d


def test_locate_refuses_heights_the_camera_cannot_locate(paper, tmp_path, capsys):
    d = _with_camera(paper, 600.0)
    assert d["valid_for"]["cameras"][0]["locate_heights_mm"] == [0.0, 600.0]
    cal = _write(tmp_path, d)
    assert main(["locate", str(cal), "--pixel", "600", "450", "--z-mm", "50", "-q"]) == 0
    capsys.readouterr()
    # one pixel outside: nothing located (exit 1), why and what would cover it
    assert main(["locate", str(cal), "--pixel", "600", "450", "--z-mm", "-30", "-q"]) == 1
    (line,) = _err_lines(capsys)
    assert "valid_for.heights" in line and "-30" in line and "to cover it" in line, line
    assert main(["locate", str(cal), "--pixel", "600", "450", "--z-mm", "-30", "--force"]) == 0
    assert any("valid_for" in ln for ln in _err_lines(capsys))
    # per pixel (issue 38): the rest is located, each one outside says why in its row,
    # exit 3 (partial)
    px = tmp_path / "px.csv"
    px.write_text("id,u_px,v_px,z_mm\na,600,450,50\nb,600,450,-30\nc,610,440,\n")
    out = tmp_path / "pts.csv"
    assert main(["locate", str(cal), "--csv", str(px), "-o", str(out), "-q"]) == 3
    (line,) = _err_lines(capsys)
    assert "1 of 3 pixel(s)" in line and ": b " in line, line
    rows = {r["id"]: r for r in csv.DictReader(out.read_text().splitlines())}
    assert [rows[i]["status"] for i in "abc"] == ["ok", "outside valid_for", "ok"], rows
    assert rows["b"]["x_mm"] == "" and "valid_for.heights" in rows["b"]["reason"], rows["b"]
    assert float(rows["a"]["x_mm"]) and float(rows["c"]["x_mm"])


def test_locate_refuses_a_joint_command_beyond_the_marks(paper, tmp_path, capsys):
    """--robot: the compensated command of the located point, checked as plan's targets."""
    from vision_cal.model.kinematics import ScaraParams, forward

    p = ScaraParams.from_json(paper["params"])
    robot = ROOT / "fixtures" / "robot_sm5.yaml"
    for q, rc in (([5.0, 30.0], 0), ([45.0, 30.0], 1)):    # joint 1 covered -20..20 deg
        over = forward(p, np.array([q]))[0]
        cal = _write(tmp_path, _with_camera(paper, 600.0, over_mm=over))
        capsys.readouterr()
        assert main(["locate", str(cal), "--pixel", "599.5", "449.5", "--robot", str(robot),
                     "-q"]) == rc
    (line,) = _err_lines(capsys)
    assert "valid_for.joints" in line and "joint 1 -20.0..20.0 deg" in line, line


# --------------------------------------------------------------------------- export

def test_export_refuses_a_model_with_an_effect_it_could_not_identify(paper, tmp_path, capsys):
    cal = _write(tmp_path, _one_side(paper))
    y = tmp_path / "c.yaml"
    assert main(["export", str(cal), "--yaml", str(y), "-q"]) == 2
    (line,) = _err_lines(capsys)
    assert "valid_for.not_identified" in line and "joint_backlash(joint 2)" in line
    assert not y.exists()
    assert main(["export", str(cal), "--yaml", str(y), "-q", "--force"]) == 0
    doc = yaml.safe_load(y.read_text())
    assert doc["extrapolated"] and "joint_backlash(joint 2)" in doc["extrapolated"][0]
    assert doc["valid_for"]["approach_sides"]["2"] == [1]
    # the paper's own file (both sides seen) exports as before, with its offsets
    good = _write(tmp_path, paper, "good.json")
    assert main(["export", str(good), "--yaml", str(tmp_path / "g.yaml"), "-q"]) == 0
    g = yaml.safe_load((tmp_path / "g.yaml").read_text())
    assert "extrapolated" not in g
    for j, o in enumerate(("joint1", "joint2")):
        assert g["controller_offsets"]["add_to_offset_deg"][o] == pytest.approx(
            paper["nominal"]["joint_zero_deg"][j] - paper["params"]["joint_zero_deg"][j])


# --------------------------------------------------------------------------- verify

def test_verify_refuses_a_check_drawn_from_a_side_never_calibrated(paper, tmp_path, capsys):
    """Checked before anything is measured or written: the check's marks (session.json)
    against the calibration's valid_for."""
    cal = _write(tmp_path, _one_side(paper))
    check = tmp_path / "check"
    check.mkdir()
    session = json.loads((ROOT / "fixtures" / "paper_sm5" / "session.json").read_text())
    session["marks"] = [{"id": f"k{i}", "joints_deg": q, "approach": [1, -1]}
                        for i, q in enumerate([[0.0, 10.0], [5.0, 20.0], [-5.0, 30.0]])]
    session.pop("images", None)
    assert main(["sheet", "--size", "A4", "--out", str(tmp_path / "sheet"), "-q"]) == 0
    session["sheet"] = json.loads((tmp_path / "sheet" / "sheet.json").read_text())
    (check / "session.json").write_text(json.dumps(session))
    out = tmp_path / "v"
    assert main(["verify", str(cal), str(check), "-o", str(out), "-q"]) == 2
    (line,) = _err_lines(capsys)
    assert "valid_for.approach2" in line and "k0" in line, line
    assert not out.exists()


def test_check_is_empty_for_an_old_file_that_does_not_say():
    assert vf_mod.check(None, ids=["a"], joints_deg=[[500.0, 0.0]]) == []


@pytest.mark.parametrize("field,value", [
    ("joints_deg", [[10.0, -10.0], [0.0, 1.0]]), ("approach_sides", {"2": [0]}),
    ("joint4_deg", "x"), ("not_identified", [{"joint": 2}]), ("heights_mm", [0.0])])
def test_a_bad_valid_for_is_one_line_naming_the_field(paper, tmp_path, capsys, field, value):
    d = copy.deepcopy(paper)
    d["valid_for"][field] = value
    cal = _write(tmp_path, d)
    assert main(["plan", str(cal), str(_inside_targets(tmp_path, paper)), "-o",
                 str(tmp_path / "p.csv"), "-q"]) == 2
    (line,) = _err_lines(capsys)
    assert f"{cal}: valid_for.{field}" in line, line


def test_plan_refuses_a_program_drawn_at_another_height(paper, tmp_path, capsys):
    """The marks were drawn at the robot file's pen_down_mm (session.json
    design.pen_down_mm); a program lowering joint 3 elsewhere puts the tool elsewhere."""
    robot = ROOT / "fixtures" / "robot_sm5.yaml"
    pen = yaml.safe_load(robot.read_text())["pen_down_mm"]
    d = copy.deepcopy(paper)
    d["valid_for"]["pen_down_mm"] = pen + 5.0
    cal = _write(tmp_path, d)
    argv = ["plan", str(cal), str(_inside_targets(tmp_path, paper)), "-o",
            str(tmp_path / "p.csv"), "--program", "spel", "--robot", str(robot), "-q"]
    assert main(argv) == 2
    (line,) = _err_lines(capsys)
    assert "valid_for.pen_down_mm" in line and f"{pen:g}" in line, line
    d["valid_for"]["pen_down_mm"] = pen
    _write(tmp_path, d)
    assert main(argv) == 0


def test_an_arm_cameras_poses_are_what_it_was_calibrated_for():
    """A handeye calibration (no marks): its poses give the joints and sides, joint 4 turned
    identifies the mount, T_flange_camera's z the camera's height above the sheet."""
    T = np.eye(4)
    T[2, 3] = 205.0
    doc = {"method": "arm_camera", "cameras": [{"T_flange_camera": T.tolist(),
                                                 "intrinsics": "declared"}],
           "poses": [{"joints_deg": [q1, q2], "approach": [s, -s], "j4_deg": j4}
                     for q1, q2, s, j4 in ((-30, 60, 1, 0), (40, -80, -1, 90), (10, 100, 1, 45))]}
    vf = vf_mod.build(doc)
    assert vf["joints_deg"] == [[-30.0, 40.0], [-80.0, 100.0]]
    assert vf["approach_sides"] == {"1": [-1, 1], "2": [-1, 1]}
    assert vf["tool_identified"] is True
    assert vf["cameras"][0]["locate_heights_mm"] == [0.0, 205.0]
    out = vf_mod.check(vf, ids=["--joints"], joints_deg=[[60.0, 0.0]], approach=[(1, 1)])
    assert [o.field for o in out] == ["joints"]
