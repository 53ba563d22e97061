"""Every message says what to do (issue 30): the probe's cases, each one line on stderr
naming the file or option and the likely cause (never a Python traceback without
--verbose: ``cli`` asserts it), exit 2; and what the console prints answers the command."""

from __future__ import annotations

import json
import logging
import math
import shutil

import pytest

from tests.commands.test_keep_files import ROBOT, arm, field_sheet  # noqa: F401
from tests.commands.test_trust import (TARGETS, assert_one_line, calibration,  # noqa: F401
                                       cli)
from tests.tool.test_placements import _places
from vision_cal.actions.arm_camera import flange_camera_line
from vision_cal.commands.main import _LowerLevelFormatter, main
from vision_cal.report.summary import format_summary


@pytest.fixture(scope="module")
def files(tmp_path_factory, calibration):  # noqa: F811
    """The inputs the cases spoil: a still-camera calibration, a joint (robot-frame)
    calibration, a calibration in metres, a printed sheet, pixel lists."""
    d = tmp_path_factory.mktemp("probe")
    doc = json.loads(calibration.read_text())
    doc["cameras"] = [{
        "images": ["a.png"], "size_px": [1200, 900], "dist": [0.0] * 5,
        "K": [[1300.0, 0, 599.5], [0, 1300.0, 449.5], [0, 0, 1]],
        "T_robot_camera": [[1, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, 700], [0, 0, 0, 1]],
        "robot_to_sheet": {"z1_deg": 0.0, "base_mm": [0.0, 0.0],
                           "sheet_matrix": [[1, 0], [0, 1]]}}]
    (d / "cam.json").write_text(json.dumps(doc))
    for name, key, value in (("dist", "dist", [0.1]),
                             ("singular", "K", [[0, 0, 0], [0, 0, 0], [0, 0, 1]]),
                             ("zeroT", "T_robot_camera", [[0] * 4] * 4)):
        bad = json.loads(json.dumps(doc))
        bad["cameras"][0][key] = value
        (d / f"cam_{name}.json").write_text(json.dumps(bad))
    metres = json.loads(calibration.read_text())
    metres["params"]["L1_mm"] /= 1000
    metres["params"]["L2_mm"] /= 1000
    (d / "metres.json").write_text(json.dumps(metres))
    (d / "px_high.csv").write_text("id,u_px,v_px,z_mm\na,10,20,0\nb,30,40,800\n")
    (d / "px_quote.csv").write_text('id,u_px,v_px\na,10,20\nb,"30,40\nc,1,2\n')
    places = [p for p, _ in _places(d)][:2]
    assert main(["calibrate", *map(str, places), "--joint", "--out", str(d / "J"), "-q"]) == 0
    assert main(["sheet", "--size", "A2", "--out", str(d / "sheet"), "-q"]) == 0
    (d / "photos").mkdir()
    (d / "photos" / "IMG_0001.jpg").write_bytes(b"\xff\xd8\xff not a photo")
    shutil.copy(calibration, d / "paper.json")
    return d


# (argv with {d} for the fixture's folder and {cal} the paper calibration, field or file
# expected in the line, words expected in it)
CASES = {
    "design-seed": (["design", ROBOT, "--sheet", "{d}/sheet/sheet.json", "--out", "{d}/o",
                     "--seed", "-5"], "--seed", ["non-negative"]),
    "iso9283-without-verify": (["design", ROBOT, "--sheet", "{d}/sheet/sheet.json", "--out",
                                "{d}/o", "--iso9283", "5"], "--iso9283", ["give --verify CAL.json"]),
    "design-verify-metres": (["design", ROBOT, "--sheet", "{d}/sheet/sheet.json", "--out",
                              "{d}/o", "--verify", "{d}/metres.json"], "params.L1_mm",
                             ["metres"]),
    "design-pilot-robot-frame": (["design", ROBOT, "--sheet", "{d}/sheet/sheet.json", "--out",
                                  "{d}/o", "--pilot", "{d}/J/calibration.json"],
                                 "J/calibration.json", ["placement's own", "place0"]),
    "plan-robot-frame": (["plan", "{d}/J/calibration.json", TARGETS, "-o", "{d}/p.csv"],
                         "J/calibration.json", ["placement's own", "J/place0/calibration.json"]),
    "sheet-pdf": (["design", ROBOT, "--sheet", "{d}/sheet/sheet.pdf", "--out", "{d}/o"],
                  "sheet.pdf", ["PDF", "sheet/sheet.json"]),
    "folder-for-calibration": (["plan", "{d}/J", TARGETS, "-o", "{d}/p.csv"], "J",
                               ["is a folder", "calibration.json"]),
    "robot-as-truth": (["simulate", "{d}/o", "--truth", ROBOT, "--out", "{d}/o"], ROBOT,
                       ["robot-template --simulated"]),
    "photos-without-session": (["{d}/photos", "--out", "{d}/o"], "session.json",
                               ["vision-cal design", "vision-cal init"]),
    "locate-dist": (["locate", "{d}/cam_dist.json", "--pixel", "10", "20"], "cameras[0].dist",
                    ["coefficients"]),
    "locate-singular-K": (["locate", "{d}/cam_singular.json", "--pixel", "10", "20"],
                          "cameras[0].K", ["positive focal length"]),
    "locate-zero-T": (["locate", "{d}/cam_zeroT.json", "--pixel", "10", "20"],
                      "cameras[0].T_robot_camera", ["bottom row 0 0 0 1"]),
    "locate-csv-height": (["locate", "{d}/cam.json", "--csv", "{d}/px_high.csv"],
                          "line 3: z_mm", ["px_high.csv", "700"]),
    "locate-csv-quote": (["locate", "{d}/cam.json", "--csv", "{d}/px_quote.csv"],
                         "line 3", ["stray quote"]),
    "locate-robot-frame": (["locate", "{d}/J/calibration.json", "--pixel", "1", "2"],
                           "J/calibration.json", ["placement's own"]),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_probe_cases_are_one_line_naming_the_cause(files, capsys, case):
    argv, where, words = CASES[case]
    argv = [str(a).format(d=files) for a in argv]
    rc, _, err = cli(argv, capsys)
    assert rc == 2, err
    assert_one_line(err, where, *words)
    assert not (files / "o" / "session.json").exists()


def test_handeye_joints_in_radians_are_named(arm, tmp_path, capsys):  # noqa: F811
    s = json.loads((arm / "session.json").read_text())
    for p in s["poses"]:
        p["joints_deg"] = [math.radians(v) for v in p["joints_deg"]]
    (arm / "session.json").write_text(json.dumps(s))
    rc, _, err = cli(["handeye", arm, "--out", tmp_path / "o"], capsys)
    assert rc == 2
    assert_one_line(err, "session.json", "poses", "radians")


def test_handeye_folder_without_session_points_to_design(tmp_path, capsys):
    (tmp_path / "arm").mkdir()
    rc, _, err = cli(["handeye", tmp_path / "arm", "--out", tmp_path / "o"], capsys)
    assert rc == 2
    assert_one_line(err, "session.json", "design --camera-on-arm")


def test_log_warnings_are_spelled_like_the_commands_own(tmp_path, capsys):
    """An unknown field in the robot file is logged: "vision-cal: warning:", never
    "WARNING:"."""
    rec = logging.LogRecord("x", logging.WARNING, "f", 1, "ignoring unknown fields", (), None)
    line = _LowerLevelFormatter("vision-cal: %(levelname)s: %(message)s").format(rec)
    assert line == "vision-cal: warning: ignoring unknown fields"
    assert rec.levelname == "WARNING"   # the record itself is left as it was


# --------------------------------------------------------------------------- what is printed

def test_a_targets_folder_prints_where_each_target_landed_first(files):
    doc = json.loads((files / "cam.json").read_text())
    doc["targets"] = [{"id": "t1", "target_mm": [0, 0], "measured_mm": [0.01, 0],
                       "error_mm": [0.01, -0.002], "error_norm_mm": 0.0102},
                      {"id": "t2", "target_mm": [5, 0], "measured_mm": [5.0, 0.02],
                       "error_mm": [-0.004, 0.02], "error_norm_mm": 0.0204}]
    text = format_summary(doc)
    first = text.splitlines()[0]
    assert first.startswith("where each target landed (2 targets")
    assert "largest 0.0204 mm (t2)" in text and "by-product" in text
    # the still camera the calibration located, with its place and what to run next
    line = next(ln for ln in text.splitlines() if ln.startswith("still camera 0"))
    assert "z 700.00 mm in the robot frame" in line and "vision-cal locate" in line


def test_the_arm_camera_line_has_units_and_says_the_height_is_not_identifiable():
    cam = {"T_flange_camera": [[1, 0, 0, 12.5], [0, 1, 0, -3.0], [0, 0, 1, 180.0],
                               [0, 0, 0, 1]],
           "T_flange_camera_std": {"translation_mm": [0.02, 0.03, 0.0]}}
    line = flange_camera_line(cam)
    assert "x 12.500 +- 0.020 mm" in line and "not identifiable" in line
    assert "+- 0.000" not in line   # no std claimed for the height it cannot see


@pytest.mark.parametrize("argv,words", [
    (["--help"], ["--opencv", "--ros"]),
    (["plan", "--help"], ["std_mm", "PLAN.failed.csv"]),
    (["calibrate", "--help"], ["measurement.json", "previous/", "summary.json"]),
    (["locate", "--help"], ["handeye", "still camera"]),
    (["handeye", "--help"], ["--jobs", "no --report", "500"]),
    (["export", "--help"], ["still camera", "cal/calibration.json --opencv"]),
])
def test_help_says_what_the_command_writes_and_reads(capsys, argv, words):
    with pytest.raises(SystemExit):
        main(argv)
    text = " ".join(capsys.readouterr().out.split())
    for w in words:
        assert w in text, w


def test_the_next_step_after_sheet_fits_the_sheet():
    """`vision-cal sheet`: a ruled sheet's next step measures its two 100 mm bars and says
    where the lengths go (--bars-mm); a marker field (--field) has no bars to measure."""
    from vision_cal.actions.sheet import SheetOutcome
    from vision_cal.sheet.field import make_field_layout
    from vision_cal.sheet.layout import make_layout

    ruled = SheetOutcome(make_layout(size="A4"), {}).lines()[-1]
    assert "100 mm bars" in ruled and "--bars-mm" in ruled
    field = SheetOutcome(make_field_layout(size="A4"), {}).lines()[-1]
    assert "bar" not in field and "flat" in field


def test_simulate_says_what_an_arm_camera_took():
    """`vision-cal simulate` of a camera-on-arm session: the photos and the poses, never
    "the simulated robot drew 0 marks"; one photo is "1 photo"."""
    from pathlib import Path

    from vision_cal.actions.simulate import SimulateOutcome
    from vision_cal.world.rehearse import SimulateResult

    photos = tuple(Path(f"p{i}.png") for i in range(30))
    arm_line = SimulateOutcome(SimulateResult(Path("arm"), photos, 0, (), (), Path("t"),
                                              n_poses=24)).line()
    assert arm_line.startswith("the simulated arm camera took 30 photos at 24 poses -> arm/")
    pen = SimulateOutcome(SimulateResult(Path("p"), photos[:1], 12, (), (), Path("t"))).line()
    assert "drew 12 marks" in pen and "; 1 photo ->" in pen


def test_a_loop_target_not_found_says_where_the_pen_really_landed():
    """loop.json: a target whose mark no photo shows takes the world's truth (off the
    paper, on a printed marker) before the measurement's 'no dot found'."""
    from types import SimpleNamespace

    import numpy as np

    from vision_cal.actions.loop import _landed, _target_results

    planned = [SimpleNamespace(id=i, status="ok", q_deg=(0.0, 0.0), approach=(1, 1))
               for i in ("g01", "g02", "g03")]
    m = SimpleNamespace(marks={}, refused={i: "no dot found for it" for i in
                                           ("g01", "g02", "g03")})
    landed = _landed({"off_paper": ["g02"], "on_marker": ["g01"]})
    res = _target_results(planned, m, {i: np.zeros(2) for i in ("g01", "g02", "g03")},
                          None, None, landed=landed)
    assert res["g01"]["reason"] == "landed on a printed marker (truth.json)"
    assert res["g02"]["reason"] == "landed off the paper (truth.json)"
    assert res["g03"]["reason"] == "no dot found for it"
