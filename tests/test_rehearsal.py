"""README "Rehearse it first" and "Rehearse a survey": the shell blocks typed exactly as the
page gives them (tests/readme.py), in one working folder.

The first block under "## Rehearse it first": each `vision-cal ...` line runs through the
command line's own entry point (in-process), any other line (the targets file) through the
shell. A simulated SM5 (the shipped template: 28 mm and 2.6/8.1 deg from the robot file's
guess, a 0.1 deg backlash in joint 2) draws and is photographed by `vision-cal simulate`,
the pilot once (one phone photo); the rest is the user's page. Then the verify check: an
unchanged robot is "still good"; the README's next block moves joint 2's zero by 0.04 deg
in a copy of the simulated robot and checks into a new folder: "re-zero joint 2" with the
change within 4 reported std. The survey block follows on a fresh sheet with a printer off
by 0.15 mm RMS.
"""

from __future__ import annotations

import csv
import json
import re

import numpy as np
import pytest
import yaml

from tests.conftest import ROOT
from tests.readme import blocks_under, type_line

pytestmark = pytest.mark.render

MOVED_Z2_DEG = 0.04


def readme_commands() -> list[str]:
    """The rehearsal: the first block under "Rehearse it first" (bench/rehearse.py too)."""
    return blocks_under("Rehearse it first")[0].commands


def type_command(line: str, cwd) -> None:
    type_line(line, cwd)


@pytest.fixture(scope="module")
def rehearsal(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("rehearsal")
    lines = readme_commands()
    for line in lines:
        type_command(line, tmp)
    return tmp, lines


def test_readme_block_is_the_whole_walkthrough(rehearsal):
    """Every step of "Calibrate your robot" is in the rehearsal, the robot's part simulated."""
    _, lines = rehearsal
    verbs = [ln.split()[1] if ln.startswith("vision-cal ") else "shell" for ln in lines]
    assert verbs.count("simulate") == 4 and verbs.count("design") == 3
    assert "sheet" in verbs and "verify" in verbs and "plan" in verbs
    assert any(re.match(r"vision-cal \S+/ --out", ln) for ln in lines)   # calibrate


def test_rehearsal_calibrates_the_hidden_robot(rehearsal):
    """The calibration of the simulated photos finds what the template hides, each within
    4 reported std (the base and z1 as the world places them, the backlash in joint 2)."""
    tmp, _ = rehearsal
    cal = json.loads((tmp / "cal" / "calibration.json").read_text())
    truth = json.loads((tmp / "plan" / "truth.json").read_text())["params"]
    p, s = cal["params"], cal["std"]
    for k in ("L1_mm", "L2_mm"):
        assert abs(p[k] - truth[k]) < 4 * s[k] + 0.01, (k, p[k], truth[k], s[k])
    for i in range(2):
        assert abs(p["joint_zero_deg"][i] - truth["joint_zero_deg"][i]) < \
            4 * s["joint_zero_deg"][i] + 0.002
        assert abs(p["base_mm"][i] - truth["base_mm"][i]) < 4 * s["base_mm"][i] + 0.01
    bl = [e for e in cal["effects"] if e["name"] == "joint_backlash" and e["joint"] == 2]
    assert bl and abs(bl[0]["deg"] - 0.1) < 4 * bl[0]["std"] + 0.002
    # the designed plan drew 8 marks twice: the floor's repeatability is measured from them
    # when they resolve it from the measurement noise (within 4 of the std it states of the
    # world's, truth.json repeatability_mm), else the stated prior (the default 0.01 mm),
    # never 0 (it read 0.0 mm where the marks' stated noise exceeded their real one)
    v = cal["verdict"]
    r_true = json.loads((tmp / "plan" / "truth.json").read_text())["repeatability_mm"]
    rp = v["repeatability"]
    assert rp["n_pairs"] == 8 and v["repeatability_mm"] > 0, rp
    if rp["measured"]:
        assert v["repeatability_source"].startswith("8 pairs"), rp
        assert abs(v["repeatability_mm"] - r_true) < 4 * rp["std_mm"], (rp, r_true)
    else:
        assert v["repeatability_source"] == "default" and "not resolved" in rp["why"], rp
        assert v["repeatability_mm"] == 0.01
    # two photos cannot measure the print (fewer than three camera places, no survey): said,
    # never "ready", a printer's deviation in the expected error; the fit's halves agree
    if cal["print"]["source"] == "one place":
        assert v["status"] == "check" and any("not measured" in r and "survey" in r
                                              for r in v["reasons"]), v["reasons"]
        # the printer's prior counted once: its shared part in the covariance (the
        # calibration's part), the rest in the print's
        pc = (cal.get("print_in_covariance") or {}).get("at_marks_mm", 0.0)
        assert v["target_std"]["print_mm"] ** 2 + pc**2 >= 0.07**2 / 2 - 1e-12
    assert cal["replication"]["agree"], cal["replication"]
    assert (tmp / "cal" / "report.html").exists()
    assert (tmp / "targets_plan.prg").exists()
    # every photo was used (none found in the folder was skipped)
    assert cal["images"] and all(im["status"] == "ok" for im in cal["images"]), cal["images"]
    # nobody wrote an images list: the photos were found in the folder
    assert "images" not in json.loads((tmp / "plan" / "session.json").read_text())


def test_verify_says_still_good_on_the_unchanged_robot(rehearsal):
    tmp, _ = rehearsal
    v = json.loads((tmp / "check_verify" / "verify.json").read_text())
    assert v["verdict"] == "still good", v["reasons"]
    assert not any(c.get("moved") for c in v["changes"].values())


def test_verify_finds_a_moved_joint_2_zero(rehearsal):
    """The README's block after the rehearsal, typed as written: joint 2's zero moved by
    0.04 deg in a copy of the simulated robot, checked into a new folder: the verdict
    names joint 2, the change agrees with 0.04 deg within 4 of its reported std, L1 and L2
    did not move. (Another sheet placed elsewhere: bench/rehearse.py.)"""
    tmp, _ = rehearsal
    block = blocks_under("Rehearse it first")[1].commands
    assert "check2/" in block[1] and block[-1].startswith("vision-cal verify"), block
    for line in block:
        type_command(line, tmp)
    moved = yaml.safe_load((tmp / "moved_robot.yaml").read_text())["hidden"]
    same = yaml.safe_load((tmp / "true_robot.yaml").read_text())["hidden"]
    assert moved["joint_zero_deg"][1] == pytest.approx(same["joint_zero_deg"][1] + MOVED_Z2_DEG)
    v = json.loads((tmp / "check2_verify" / "verify.json").read_text())
    assert v["verdict"].startswith("re-zero joint 2: add -"), v["reasons"]
    z2 = v["changes"]["z2_deg"]
    assert z2["moved"] and abs(z2["delta"] - MOVED_Z2_DEG) < 4 * z2["std"], z2
    # the README quotes the verdict this run writes (not a figure typed apart from it)
    assert f'Its verdict: "{v["verdict"]}"' in " ".join(
        (ROOT / "README.md").read_text().split()), v["verdict"]
    assert not v["changes"]["L1_mm"]["moved"] and not v["changes"]["L2_mm"]["moved"]


def test_the_compensated_targets_program_hits_its_targets(rehearsal):
    """Step 11 on the simulated robot: the compensated program's marks lie within 0.05 mm
    RMS of their targets (truth.json: where the pen really went; the calibration predicts
    a few micrometres, the robot's repeatability is 0.01 mm per axis), and measuring the
    photos (`vision-cal hits/`) finds each miss to within 0.05 mm of the truth."""
    import numpy as np

    tmp, _ = rehearsal
    truth = json.loads((tmp / "hits" / "truth.json").read_text())["marks"]
    cal = json.loads((tmp / "hits_cal" / "calibration.json").read_text())
    rows = cal["targets"]
    assert len(rows) == 6
    true_miss = np.array([np.subtract(truth[r["id"]], r["target_mm"]) for r in rows])
    assert float(np.sqrt(np.mean(np.sum(true_miss**2, axis=1)))) < 0.05
    seen = np.array([r["error_mm"] for r in rows])
    assert np.all(np.hypot(*(seen - true_miss).T) < 0.05), (seen, true_miss)
    # the misses agree with what the plan predicted (targets_plan.csv std_mm: per axis, the
    # calibration's covariance, the robot's repeatability, what the model leaves, the print
    # - here not measured, a printer's 0.07 mm, which this world's perfect print leaves unused):
    # per axis under 3 times it (the check bench/walkthrough.py makes on 27 targets), and
    # each miss inside its own 99.9 % radius (all six by noise alone 99.4 % of the time)
    import csv

    plan = {r["id"]: r for r in csv.DictReader((tmp / "targets_plan.csv").read_text()
                                                .splitlines())}
    std = np.array([float(plan[r["id"]]["std_mm"]) for r in rows])
    parts = ("std_calibration_mm", "std_repeatability_mm", "std_unexplained_mm",
             "std_print_mm", "std_paper_scale_mm")
    for r in rows:   # std_mm is its parts' root sum of squares
        assert float(plan[r["id"]]["std_mm"]) == pytest.approx(
            np.sqrt(sum(float(plan[r["id"]][k]) ** 2 for k in parts)), rel=1e-6)
    rep = yaml.safe_load((tmp / "true_robot.yaml").read_text())["hidden"]["repeatability_mm"]
    assert np.all(std >= rep * 0.99), std     # the repeatability is in it
    per_axis = float(np.sqrt(np.mean(np.sum(true_miss**2, axis=1)) / 2))
    assert per_axis < 3 * float(np.sqrt(np.mean(std**2))), (per_axis, std)
    r999 = np.sqrt(-2 * np.log(0.001))
    assert np.all(np.hypot(*true_miss.T) < r999 * std), (np.hypot(*true_miss.T), std)


def test_the_report_tells_the_controller_the_robot_files_offsets(rehearsal):
    """Issue 29 section 1: the informative plan was placed with the pilot's model, yet
    every "nominal" and "add to the controller" is the robot file's (the controller runs
    it): the report's offsets are the robot file's zeros minus the calibrated ones, within
    0.01 deg of the robot file's minus the true zeros (the simulated robot's), and the
    pilot's model is named the plan's starting model."""
    tmp, _ = rehearsal
    robot = yaml.safe_load((tmp / "robot.yaml").read_text())
    truth = json.loads((tmp / "plan" / "truth.json").read_text())["params"]
    cal = json.loads((tmp / "cal" / "calibration.json").read_text())
    pilot = json.loads((tmp / "pilot_cal" / "calibration.json").read_text())
    assert cal["nominal"]["joint_zero_deg"] == robot["joint_zero_deg"]
    assert cal["starting_model"]["joint_zero_deg"] == pilot["params"]["joint_zero_deg"]
    report = json.loads((tmp / "cal" / "report.json").read_text())
    offsets = {o["joint"]: o["add_to_offset_deg"]
               for o in report["actions"]["controller_offsets"]}
    for j in (1, 2):
        want = robot["joint_zero_deg"][j - 1] - truth["joint_zero_deg"][j - 1]
        assert abs(offsets[j] - want) < 0.01, (j, offsets[j], want)
        assert f"joint {j}: {offsets[j]:+.4f} deg" in report["actions"]["controller_offsets_text"]
    assert "robot file" in report["actions"]["controller_offsets_text"]
    html = (tmp / "cal" / "report.html").read_text()
    assert f"{offsets[2]:+.4f}" in html and "starting model" in html


def test_targets_just_beyond_what_the_marks_covered(rehearsal):
    """Issue 38: 25 targets inside the joints the marks covered and three beyond joint 1's
    range (1.7, 2.6 and 15 deg): the rehearsal's calibration plans those its own expected
    error still holds for, lists the others in targets_plan.failed.csv with why and what
    would cover it, and exits 3 (planned in part)."""
    from vision_cal.dataset.calibration import load_calibration

    tmp, _ = rehearsal
    model, doc = load_calibration(tmp / "cal" / "calibration.json")
    (lo1, hi1), (lo2, hi2) = doc["valid_for"]["joints_deg"]
    rng = np.random.default_rng(38)
    q = np.column_stack([rng.uniform(lo1 + 3, hi1 - 3, 25),
                         rng.uniform(max(lo2, 0.0) + 20, hi2 - 3, 25)])   # elbow +1 side
    beyond = {"j1+1.7": 1.7, "j1+2.6": 2.6, "j1+15": 15.0}
    q = np.vstack([q, [[hi1 + d, (max(lo2, 0.0) + hi2) / 2] for d in beyond.values()]])
    ids = [f"in{i}" for i in range(25)] + list(beyond)
    xy = model.predict(q, np.ones_like(q))
    (tmp / "edge.csv").write_text("id,x_mm,y_mm\n" + "".join(
        f"{i},{x:.4f},{y:.4f}\n" for i, (x, y) in zip(ids, xy)))
    type_line("vision-cal plan cal/calibration.json edge.csv -o edge_plan.csv", tmp, expect=3)
    planned = [r["id"] for r in csv.DictReader((tmp / "edge_plan.csv").read_text()
                                               .splitlines())]
    failed = {r["id"]: r["reason"] for r in csv.DictReader(
        (tmp / "edge_plan.failed.csv").read_text().splitlines())}
    assert set(planned) >= {f"in{i}" for i in range(25)} | {"j1+1.7", "j1+2.6"}, (planned, failed)
    assert "j1+15" in failed and "valid_for.joints" in failed["j1+15"], failed
    assert "to cover it: draw marks there" in failed["j1+15"]
    print(f"planned beyond: {sorted(set(planned) & set(beyond))}, left out: {sorted(failed)}")


def test_a_survey_rehearsed_measures_the_print(rehearsal):
    """The README's survey block typed as written: the blank sheet photographed from six
    places with a printer 0.15 mm RMS off its layout; survey.json's markers as printed
    within 0.05 mm RMS of the truth (the layout is 0.15 mm off); the pilot's one photo is
    measured against the survey (calibration.json print source "survey"), so its verdict
    does not ask for the print to be measured."""
    tmp, _ = rehearsal
    for line in blocks_under("Rehearse a survey")[0].commands:
        type_command(line, tmp)
    survey = json.loads((tmp / "sheet2" / "survey.json").read_text())
    truth = json.loads((tmp / "survey_photos" / "truth.json").read_text())["print"]["markers"]
    err = np.concatenate([np.subtract(m["corners_mm"], truth[str(m["id"])])
                          for m in survey["as_printed"]["markers"]])
    layout = np.concatenate([np.subtract(m["declared_mm"], truth[str(m["id"])])
                             for m in survey["as_printed"]["markers"]])
    rms = lambda e: float(np.sqrt(np.mean(np.sum((e - e.mean(0)) ** 2, axis=1))))  # noqa: E731
    assert rms(layout) > 0.1 and rms(err) < 0.05, (rms(err), rms(layout))
    cal = json.loads((tmp / "pilot2_cal" / "calibration.json").read_text())
    assert (cal.get("print") or {}).get("source") == "survey", cal.get("print")
    assert "print_one_place" not in cal["verdict"].get("reason_codes", [])
    # the pilot against the truth (issue 37: the grid reference taken at its layout read the
    # printer's displacement as the marks' error, L1 7.9 mm and 6.8 std off, a false
    # joint_scale of -1.9 % and 2.5 mm of sheet height on a flat sheet): each parameter
    # within 4 of its std, joint 2's backlash (which one approach side cannot identify)
    # folded into its zero by up to half its size; no effect claimed, the marks within the
    # print's limit on them (calibration.json print.limit_mm, 2-D RMS)
    world = json.loads((tmp / "pilot2" / "truth.json").read_text())
    t, p, sd = world["params"], cal["params"], cal["std"]
    folded = sum(e["deg"] for e in world["effects"] if e["name"] == "joint_backlash") / 2
    for k in ("L1_mm", "L2_mm"):
        assert abs(p[k] - t[k]) < 4 * sd[k], (k, p[k], t[k], sd[k])
    for i in (0, 1):
        assert abs(p["joint_zero_deg"][i] - t["joint_zero_deg"][i]) < \
            4 * sd["joint_zero_deg"][i] + (folded if i == 1 else 0.0), (i, p, t, sd)
    assert not [e["name"] for e in cal["effects"]], cal["effects"]
    assert not cal["valid_for"].get("heights_mm") or max(
        abs(h) for h in cal["valid_for"]["heights_mm"]) == 0.0, cal["valid_for"]
    miss = np.array([np.subtract(m["measured_mm"], world["marks"][k])
                     for k, m in cal["marks"].items()])
    assert np.sqrt(np.mean(np.sum(miss**2, axis=1))) < cal["print"]["limit_mm"], miss
