"""Every command keeps the user's files (issue 30): an output that is an input, or that holds
another command's results, is refused (exit 2, one line, the input byte-identical) or moved
to previous/ (the same bytes there); a folder being written carries a lock a second run
reports in one line; an interrupted run leaves nothing that looks current."""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import subprocess
import sys

import pytest

from tests.commands.test_trust import (PAPER, ROOT, TARGETS, assert_one_line,
                                       calibration, cli, snapshot)  # noqa: F401
import vision_cal.actions.calibrate as calibrate_action
import vision_cal.actions.calibrate as placements
from tests.tool.test_placements import _places
from vision_cal.dataset.session import MAX_POSES
from vision_cal.commands.main import main
from vision_cal.dataset.out_folder import LOCK, RECORD

ROBOT = "fixtures/robot_sm5.yaml"


@pytest.fixture()
def pen_cal(tmp_path, calibration):  # noqa: F811
    """A pen calibration's folder: calibration.json and (a stand-in) measurement.json."""
    d = tmp_path / "cal"
    shutil.copytree(calibration.parent, d)
    (d / "measurement.json").write_text('{"format": "a pen run\'s measurement"}\n')
    record = json.loads((d / RECORD).read_text())   # as calibrate records it
    record["runs"]["calibrate"].append("measurement.json")
    (d / RECORD).write_text(json.dumps(record))
    return d


@pytest.fixture(scope="module")
def field_sheet(tmp_path_factory):
    d = tmp_path_factory.mktemp("field") / "sheet"
    assert main(["sheet", "--field", "--size", "A2", "--out", str(d), "-q"]) == 0
    return d


@pytest.fixture()
def arm(tmp_path, field_sheet, capsys):
    """A camera-on-arm design (session.json, program.prg) with 10 photos of an earlier one."""
    d = tmp_path / "arm"
    rc, _, _ = cli(["design", ROBOT, "--sheet", field_sheet / "sheet.json", "--camera-on-arm",
                    "--n-poses", "10", "--repeats", "0", "--out", d, "-q"], capsys)
    assert rc == 0
    for i in range(10):
        (d / f"pose_{i:03d}.png").write_bytes(b"\x89PNG not really")
    return d


# --------------------------------------------------------------------------- history

@pytest.mark.parametrize("opts,field", [
    (["-o", "{cal}"], "-o"),
    (["--plot", "{cal}"], "--plot"),
    (["-o", "{x}", "--plot", "{x}"], "--plot"),
    (["-o", "{png}"], "-o"),
], ids=["csv-over-calibration", "png-over-calibration", "csv-and-png-one-path",
        "csv-over-a-png"])
def test_history_never_writes_over_a_calibration_or_its_other_output(tmp_path, pen_cal,
                                                                     capsys, opts, field):
    hist = tmp_path / "hist"
    shutil.copytree(pen_cal, hist / "a")
    (tmp_path / "h.png").write_bytes(b"\x89PNG earlier plot")
    names = {"cal": hist / "a" / "calibration.json", "x": tmp_path / "h.out",
             "png": tmp_path / "h.png"}
    before = snapshot(tmp_path)
    rc, _, err = cli(["history", hist, *[o.format(**names) for o in opts]], capsys)
    assert rc == 2
    assert_one_line(err, field)
    assert snapshot(tmp_path) == before


def test_history_replaces_its_own_earlier_csv(tmp_path, pen_cal, capsys):
    out = tmp_path / "h.csv"
    assert cli(["history", pen_cal, "-o", out, "-q"], capsys)[0] == 0
    first = out.read_bytes()
    assert cli(["history", pen_cal, "-o", out, "-q"], capsys)[0] == 0
    assert out.read_bytes() == first


# --------------------------------------------------------------------------- locate

@pytest.mark.parametrize("target", ["cal", "csv"])
def test_locate_never_writes_over_its_inputs(tmp_path, pen_cal, capsys, target):
    px = tmp_path / "px.csv"
    px.write_text("id,u_px,v_px\na,10,20\n")
    cal = pen_cal / "calibration.json"
    before = snapshot(tmp_path)
    rc, _, err = cli(["locate", cal, "--csv", px, "-o", {"cal": cal, "csv": px}[target]],
                     capsys)
    assert rc == 2
    assert_one_line(err, "-o", "choose another name")
    assert snapshot(tmp_path) == before


# --------------------------------------------------------------------------- handeye

def test_handeye_into_its_photo_folder_is_refused(arm, capsys):
    before = snapshot(arm)
    rc, _, err = cli(["handeye", arm, "--out", arm], capsys)
    assert rc == 2
    assert_one_line(err, "--out", "input")
    assert snapshot(arm) == before


def test_handeye_over_a_pen_calibration_moves_it_to_previous(arm, pen_cal, capsys):
    before = snapshot(pen_cal)
    rc, _, err = cli(["handeye", arm, "--out", pen_cal, "-q"], capsys)
    assert rc == 1   # the photos are not photos: nothing calibrated
    # nothing of the pen run looks current; every byte of it is in previous/
    assert not (pen_cal / "calibration.json").exists()
    assert not (pen_cal / "measurement.json").exists()
    after = snapshot(pen_cal)
    for name, digest in before.items():
        if "/" not in name and not name.startswith("."):
            assert after[f"previous/calibrate/{name}"] == digest, name
    assert not (pen_cal / LOCK).exists()


def test_handeye_says_why_no_photo_was_usable(arm, tmp_path, capsys):
    """Photos that are symlinks out of the folder: the reason is in the one line."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    for p in sorted(arm.glob("pose_*.png")):
        target = elsewhere / p.name
        p.rename(target)
        p.symlink_to(target)
    rc, _, err = cli(["handeye", arm, "--out", tmp_path / "o"], capsys)
    assert rc == 1
    assert_one_line(err, "0 of 10 photos usable", "outside the dataset folder")
    # the measurement's own progress line: every photo refused at its listing
    assert re.search(r"vision-cal: progress: measure \w+: 0/0 photos .*none to measure", err), err
    assert not (tmp_path / "o").exists()


def test_handeye_image_outside_the_folder_is_one_line(arm, tmp_path, capsys):
    s = json.loads((arm / "session.json").read_text())
    s["poses"][2]["image"] = "../x.png"
    (arm / "session.json").write_text(json.dumps(s))
    rc, _, err = cli(["handeye", arm, "--out", tmp_path / "o"], capsys)
    assert rc == 2
    assert_one_line(err, "poses[2].image", "inside the dataset folder")


def test_handeye_session_of_too_many_poses_is_refused_before_measuring(arm, tmp_path,
                                                                       capsys):
    s = json.loads((arm / "session.json").read_text())
    s["poses"] = [dict(s["poses"][0], image=f"p{i}.png") for i in range(MAX_POSES + 1)]
    (arm / "session.json").write_text(json.dumps(s))
    rc, _, err = cli(["handeye", arm, "--out", tmp_path / "o"], capsys)
    assert rc == 2
    assert_one_line(err, "poses", f"at most {MAX_POSES}")


# --------------------------------------------------------------------------- design

def test_design_camera_on_arm_over_earlier_photos_is_refused(arm, field_sheet, capsys):
    before = snapshot(arm)
    rc, _, err = cli(["design", ROBOT, "--sheet", field_sheet / "sheet.json",
                      "--camera-on-arm", "--n-poses", "24", "--out", arm], capsys)
    assert rc == 2
    assert_one_line(err, "--out", "photos")
    assert snapshot(arm) == before


@pytest.mark.parametrize("opts,field,words", [
    (["--n-poses", "100000"], "--n-poses", "at most 500"),
    (["--n-poses", "3"], "--n-poses", "at least 8"),
    (["--seed", "-5"], "--seed", "non-negative"),
])
def test_design_camera_on_arm_bounds(tmp_path, field_sheet, capsys, opts, field, words):
    rc, _, err = cli(["design", ROBOT, "--sheet", field_sheet / "sheet.json",
                      "--camera-on-arm", "--out", tmp_path / "o", *opts], capsys)
    assert rc == 2
    assert_one_line(err, field, words)
    assert not (tmp_path / "o").exists()


# --------------------------------------------------------------------------- verify

def test_verify_into_the_calibration_folder_is_refused(tmp_path, pen_cal, capsys):
    check = tmp_path / "check"
    check.mkdir()
    before = snapshot(pen_cal)
    rc, _, err = cli(["verify", pen_cal / "calibration.json", check, "-o", pen_cal], capsys)
    assert rc == 2
    assert_one_line(err, "-o", "CAL.json")
    assert snapshot(pen_cal) == before


# --------------------------------------------------------------------------- sheet

def test_sheet_over_another_sheet_is_refused(field_sheet, tmp_path, capsys):
    d = tmp_path / "sheet"
    shutil.copytree(field_sheet, d)
    before = snapshot(d)
    rc, _, err = cli(["sheet", "--size", "A4", "--field", "--out", d], capsys)
    assert rc == 2
    assert_one_line(err, "sheet.json", "another sheet")
    assert snapshot(d) == before
    # the same sheet again is its own earlier output: written, the same bytes, the
    # earlier files in previous/sheet/
    assert cli(["sheet", "--field", "--size", "A2", "--out", d, "-q"], capsys)[0] == 0
    after = snapshot(d)
    assert {n: after[n] for n in before} == before
    assert {n.removeprefix("previous/sheet/"): h for n, h in after.items()
            if n.startswith("previous/")} == {n: h for n, h in before.items()
                                              if not n.startswith(".")}


# --------------------------------------------------------------------------- calibrate --joint

def test_joint_rerun_retires_the_placements_it_does_not_write(tmp_path, capsys):
    places = [d for d, _ in _places(tmp_path)]
    out = tmp_path / "X"
    assert cli(["calibrate", *places, "--joint", "--out", out, "-q"], capsys)[0] == 0
    before = snapshot(out)
    assert cli(["calibrate", *places[:2], "--joint", "--out", out, "-q"], capsys)[0] == 0
    # the third placement of the earlier run is not beside this run's top file ...
    assert not (out / "place2").exists()
    top = json.loads((out / "calibration.json").read_text())
    assert [p["folder"] for p in top["placements"]] == ["place0", "place1"]
    # ... but kept, byte for byte, in previous/
    after = snapshot(out)
    for n in ("place2/calibration.json", "calibration.json", "place0/calibration.json"):
        assert after[f"previous/calibrate/{n}"] == before[n]
    # the placements this run writes again keep their detection caches
    assert [n for n in after if n.startswith("place0/.cache/")] == \
        [n for n in before if n.startswith("place0/.cache/")]


def test_joint_folders_with_one_name_get_their_own_outputs(tmp_path, capsys):
    places = [d for d, _ in _places(tmp_path)][:2]
    named = []
    for day, d in zip(("d1", "d2"), places):
        (tmp_path / day).mkdir()
        named.append(d.rename(tmp_path / day / "plan"))
    out = tmp_path / "X"
    rc, _, err = cli(["calibrate", *named, "--joint", "--out", out, "-q"], capsys)
    assert rc == 0, err
    assert (out / "d1-plan" / "calibration.json").is_file()
    assert (out / "d2-plan" / "calibration.json").is_file()


def test_ctrl_c_during_a_joint_run_leaves_nothing_that_looks_current(tmp_path, capsys,
                                                                      monkeypatch):
    places = [d for d, _ in _places(tmp_path)][:2]
    out = tmp_path / "X"
    assert cli(["calibrate", *places, "--joint", "--out", out, "-q"], capsys)[0] == 0
    before = snapshot(out)

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(placements, "calibrate_placed", interrupted)
    rc, _, _ = cli(["calibrate", *places, "--joint", "--out", out, "-q"], capsys)
    assert rc == 130
    after = snapshot(out)
    assert not [n for n in after if n.endswith("calibration.json")
                and "previous/" not in n]
    for n in ("calibration.json", "place0/calibration.json", "place1/calibration.json"):
        assert after[f"previous/calibrate/{n}"] == before[n], n
    assert not (out / LOCK).exists()


# --------------------------------------------------------------------------- two runs at once

@pytest.fixture()
def live_pid():
    p = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    yield p.pid
    p.kill()
    p.wait()


def _lock(folder, pid):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / LOCK).write_text(json.dumps({"command": "calibrate", "pid": pid,
                                           "host": socket.gethostname(),
                                           "started": "2026-01-01 10:00:00"}))


def test_a_second_run_into_a_locked_folder_is_refused(tmp_path, pen_cal, capsys, live_pid):
    _lock(pen_cal, live_pid)
    before = snapshot(pen_cal)
    rc, _, err = cli(["calibrate", "fixtures/paper_sm5", "--out", pen_cal], capsys)
    assert rc == 2
    assert_one_line(err, "--out", f"pid {live_pid}", "another run")
    assert snapshot(pen_cal) == before


def test_a_lock_left_by_a_dead_run_is_taken_over(tmp_path, arm, capsys):
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    out = tmp_path / "o"
    _lock(out, p.pid)
    rc, _, err = cli(["handeye", arm, "--out", out], capsys)
    assert rc == 1 and "another run" not in err   # it ran (and found no usable photo)
    assert not (out / LOCK).exists()


def test_the_lock_is_held_while_the_run_writes(tmp_path, capsys, monkeypatch):
    """While a calibration runs, its folder carries the lock with this process's pid."""
    seen = {}

    def spy(folder, *, out_dir, **k):
        seen.update(json.loads((out_dir / LOCK).read_text()))
        raise KeyboardInterrupt

    monkeypatch.setattr(calibrate_action, "calibrate_dataset", spy)
    out = tmp_path / "o"
    rc, _, _ = cli(["calibrate", "fixtures/paper_sm5", "--out", out], capsys)
    assert rc == 130
    assert seen["pid"] == os.getpid() and seen["command"] == "calibrate"
    assert not (out / LOCK).exists()


def test_init_never_writes_over_its_plan(tmp_path, capsys):
    plan = tmp_path / "plan"
    shutil.copytree("fixtures/paper_sm5", plan)
    (tmp_path / "photos").mkdir()
    before = snapshot(tmp_path)
    rc, _, err = cli(["init", tmp_path / "photos", "--plan", plan / "session.json", "-o",
                      plan / "session.json"], capsys)
    assert rc == 2
    assert_one_line(err, "-o", "is the input --plan")
    assert snapshot(tmp_path) == before


def test_choosing_many_camera_poses_shows_progress(tmp_path, field_sheet, capsys):
    rc, _, err = cli(["design", ROBOT, "--sheet", field_sheet / "sheet.json",
                      "--camera-on-arm", "--n-poses", "100", "--out", tmp_path / "o"], capsys)
    assert rc == 0
    assert "vision-cal: progress: plan camera poses: 100/100 poses" in err


@pytest.mark.parametrize("opts,field", [
    (["--yaml", "{robot}", "--robot", "{robot}"], "--yaml"),
    (["--urdf", "{other}"], "--urdf"),
], ids=["yaml-over-robot-file", "urdf-over-a-calibration"])
def test_export_never_writes_over_the_robot_file_or_a_calibration(tmp_path, pen_cal, capsys,
                                                                  opts, field):
    shutil.copy(ROBOT, tmp_path / "robot.yaml")
    shutil.copy(pen_cal / "calibration.json", tmp_path / "other.json")
    names = {"robot": tmp_path / "robot.yaml", "other": tmp_path / "other.json"}
    before = snapshot(tmp_path)
    rc, _, err = cli(["export", pen_cal / "calibration.json",
                      *[o.format(**names) for o in opts]], capsys)
    assert rc == 2
    assert_one_line(err, field)
    assert snapshot(tmp_path) == before


def test_plan_never_writes_over_a_calibration(tmp_path, pen_cal, capsys):
    other = tmp_path / "other" / "calibration.json"
    other.parent.mkdir()
    shutil.copy(pen_cal / "calibration.json", other)
    before = snapshot(tmp_path)
    rc, _, err = cli(["plan", pen_cal / "calibration.json", "fixtures/targets_origin.csv",
                      "-o", other], capsys)
    assert rc == 2
    assert_one_line(err, "-o", "holds JSON")
    assert snapshot(tmp_path) == before


# --------------------------------------------------------------------------- every command

@pytest.fixture(scope="module")
def world(tmp_path_factory, calibration):  # noqa: F811
    """Every command's inputs, cheap: calibrate's output folder (cal/, recorded), a sheet
    (sheet's folder), the paper's dataset, targets, the robot file, a simulated robot, a
    scene, an empty photo folder, pose pairs, pixels."""
    w = tmp_path_factory.mktemp("world")
    shutil.copytree(calibration.parent, w / "cal")
    assert main(["sheet", "--size", "A4", "--out", str(w / "sheet"), "-q"]) == 0
    shutil.copytree(PAPER, w / "paper")
    shutil.copy(TARGETS, w / "targets.csv")
    shutil.copy(ROBOT, w / "robot.yaml")
    assert main(["robot-template", "--simulated", "-o", str(w / "true.yaml"), "-q"]) == 0
    (w / "scenes").mkdir()
    shutil.copy(ROOT / "renders" / "default.yaml", w / "scenes" / "scene.yaml")
    (w / "photos").mkdir()
    (w / "pairs").mkdir()
    shutil.copy(ROOT / "fixtures" / "handeye_pairs" / "pairs.json", w / "pairs")
    (w / "px.csv").write_text("id,u_px,v_px\na,10,20\n")
    return w


@pytest.fixture()
def w(tmp_path, world):
    d = tmp_path / "w"
    shutil.copytree(world, d)
    return d


def _argv(argv, w):
    """``{name}`` in ``argv`` is ``w/name``; ``{o}`` a new path beside ``w``."""
    names = {p.name: str(p) for p in w.iterdir()} | {"o": str(w.parent / "o")}
    return [re.sub(r"\{([^}]+)\}", lambda m: names[m.group(1)], a) for a in argv]


#: each command's output aimed at one of its inputs (or a file for its folder, a folder
#: inside its input): refused, one line naming the option, saying what to do instead
AT_AN_INPUT = [
    ("calibrate", ["calibrate", "{paper}", "--out", "{paper}"], "--out", "is the input DIR"),
    ("calibrate-inside", ["calibrate", "{paper}", "--out", "{paper}/results"], "--out",
     "inside the input DIR"),
    ("sheet", ["sheet", "--out", "{robot.yaml}"], "--out", "expected a folder"),
    ("design", ["design", "{robot.yaml}", "--sheet", "{sheet}/sheet.json", "--out",
                "{sheet}/sheet.json"], "--out", "expected a folder"),
    ("handeye", ["handeye", "--poses", "{pairs}/pairs.json", "--out", "{pairs}"], "--out",
     "holds the input --poses"),
    ("verify", ["verify", "{cal}/calibration.json", "{photos}", "-o", "{cal}"], "-o",
     "holds the input CAL.json"),
    ("survey", ["survey", "{photos}", "--sheet", "{sheet}/sheet.json", "--out", "{photos}"],
     "--out", "is the input PHOTOS/"),
    ("simulate", ["simulate", "{paper}", "--truth", "{true.yaml}", "--out", "{true.yaml}"],
     "--out", "expected a folder"),
    ("render", ["render", "{scenes}/scene.yaml", "--out", "{scenes}"], "--out",
     "holds scene.yaml"),
    ("loop", ["loop", "{scenes}/scene.yaml", "--out", "{scenes}"], "--out", "holds scene.yaml"),
    ("plan", ["plan", "{cal}/calibration.json", "{targets.csv}", "-o", "{targets.csv}"], "-o",
     "is the input TARGETS.csv"),
    ("export", ["export", "{cal}/calibration.json", "--yaml", "{robot.yaml}", "--robot",
                "{robot.yaml}"], "--yaml", "is the input --robot"),
    ("history", ["history", "{cal}", "-o", "{cal}/calibration.json"], "-o", "holds JSON"),
    ("locate", ["locate", "{cal}/calibration.json", "--csv", "{px.csv}", "-o", "{px.csv}"],
     "-o", "is the input --csv"),
    ("init", ["init", "{photos}", "--plan", "{paper}/session.json", "-o",
              "{paper}/session.json"], "-o", "is the input --plan"),
    ("robot-template", ["robot-template", "-o", "{robot.yaml}"], "--out", "exists"),
]


@pytest.mark.parametrize("argv,field,words", [c[1:] for c in AT_AN_INPUT],
                         ids=[c[0] for c in AT_AN_INPUT])
def test_no_command_writes_over_its_input(w, capsys, argv, field, words):
    before = snapshot(w)
    rc, _, err = cli(_argv(argv, w), capsys)
    assert rc == 2
    line = assert_one_line(err, field, words)
    assert any(k in line for k in ("choose", "give", "remove")), line   # what to do instead
    assert snapshot(w) == before


def test_the_table_covers_every_command():
    from vision_cal.commands.main import SUBCOMMANDS

    assert {c[1][0] for c in AT_AN_INPUT} == set(SUBCOMMANDS)
    assert {c[0][0] for c in WRONG_KIND} >= set(SUBCOMMANDS) - {"sheet", "robot-template"}


#: each command fed the wrong kind of input (the sheet's PDF for a JSON, YAML or CSV, a
#: folder for a file, a file for a folder): one line naming the file and what to give
WRONG_KIND = [
    (["calibrate", "{sheet}/sheet.pdf", "--out", "{o}"], "sheet.pdf", "is a PDF"),
    (["design", "{sheet}/sheet.pdf", "--sheet", "{sheet}/sheet.json", "--out", "{o}"],
     "sheet.pdf", "expected the robot file"),
    (["design", "{robot.yaml}", "--sheet", "{sheet}", "--out", "{o}"], "sheet",
     "sheet/sheet.json"),
    (["handeye", "--poses", "{sheet}/sheet.pdf", "--out", "{o}"], "sheet.pdf",
     "expected the pose pairs file"),
    (["handeye", "{sheet}/sheet.pdf", "--out", "{o}"], "sheet.pdf", "expected a folder"),
    (["verify", "{sheet}/sheet.pdf", "{photos}", "-o", "{o}"], "sheet.pdf",
     "expected the calibration.json"),
    (["survey", "{photos}", "--sheet", "{sheet}/sheet.pdf", "--out", "{o}"], "sheet.pdf",
     "pass the sheet.json"),
    (["simulate", "{paper}", "--truth", "{sheet}/sheet.pdf", "--out", "{o}"], "sheet.pdf",
     "expected the simulated robot's file"),
    (["render", "{sheet}/sheet.pdf", "--out", "{o}"], "sheet.pdf", "expected a scene file"),
    (["loop", "{scenes}", "--out", "{o}"], "scenes", "expected a scene file"),
    (["plan", "{sheet}/sheet.pdf", "{targets.csv}", "-o", "{o}.csv"], "sheet.pdf",
     "expected the calibration.json"),
    (["plan", "{cal}", "{targets.csv}", "-o", "{o}.csv"], "cal",
     "cal/calibration.json"),
    (["plan", "{cal}/calibration.json", "{cal}/calibration.json", "-o", "{o}.csv"],
     "calibration.json", "is JSON, expected a targets CSV"),
    (["plan", "{cal}/calibration.json", "{targets.csv}", "-o", "{o}.csv", "--robot",
      "{sheet}", "--program", "spel"], "sheet", "expected the robot file"),
    (["export", "{sheet}/sheet.pdf", "--yaml", "{o}.yaml"], "sheet.pdf",
     "expected the calibration.json"),
    (["history", "{sheet}/sheet.pdf"], "sheet.pdf", "not a folder"),
    (["locate", "{sheet}/sheet.pdf", "--pixel", "1", "1"], "sheet.pdf",
     "expected the calibration.json"),
    (["init", "{photos}", "--plan", "{sheet}/sheet.pdf"], "sheet.pdf",
     "expected a dataset's session.json"),
]


@pytest.mark.parametrize("argv,name,words", WRONG_KIND,
                         ids=[f"{c[0][0]}-{i}" for i, c in enumerate(WRONG_KIND)])
def test_the_wrong_kind_of_input_says_what_to_give(w, capsys, argv, name, words):
    before = snapshot(w)
    rc, _, err = cli(_argv(argv, w), capsys)
    assert rc == 2
    line = assert_one_line(err, name, words)
    assert "sheet.pdf: is a PDF, expected a text file" not in line   # says which
    assert snapshot(w) == before
    assert not (w.parent / "o").exists()


# ----------------------------------------- into another command's output folder (issue 38)

def test_handeye_twice_into_a_pen_calibration_never_drops_it(w, capsys):
    """`handeye --poses` run twice into calibrate's folder: the pen calibration is in
    previous/calibrate/ after both (previous/ kept one run: the second deleted it), the
    first hand-eye in previous/handeye/."""
    pen = snapshot(w / "cal")
    argv = ["handeye", "--poses", w / "pairs" / "pairs.json", "--out", w / "cal", "-q"]
    assert cli(argv, capsys)[0] == 0
    first = (w / "cal" / "calibration.json").read_bytes()
    assert cli(argv, capsys)[0] == 0
    after = snapshot(w / "cal")
    for n, h in pen.items():
        if not n.startswith("."):
            assert after[f"previous/calibrate/{n}"] == h, n
    assert (w / "cal" / "previous" / "handeye" / "calibration.json").read_bytes() == first
    # and calibrate over the hand-eye moves that one aside, the pen run's stays
    assert cli(["calibrate", PAPER, "--out", w / "cal", "-q"], capsys)[0] == 0
    after = snapshot(w / "cal")
    assert "previous/handeye/calibration.json" in after
    assert after["previous/calibrate/calibration.json"] == pen["calibration.json"]


@pytest.mark.parametrize("argv,words", [
    (["render", "{scenes}/scene.yaml", "--out", "{cal}"], "holds calibration.json"),
    (["loop", "{scenes}/scene.yaml", "--out", "{sheet}"], "holds sheet.json"),
], ids=["render-into-calibration", "loop-into-sheet"])
def test_a_folder_of_its_own_is_refused_over_another_commands(w, capsys, argv, words):
    before = snapshot(w)
    rc, _, err = cli(_argv(argv, w), capsys)
    assert rc == 2
    assert_one_line(err, "--out", words, "choose an empty folder")
    assert snapshot(w) == before


@pytest.mark.parametrize("argv,rc", [
    (["sheet", "--size", "A4", "--out", "{cal}", "-q"], 0),
    (["plan", "{cal}/calibration.json", "{targets.csv}", "-o", "{cal}/plan.csv", "--force",
      "-q"], 3),   # planned in part: a target of the fixture is out of reach
], ids=["sheet", "plan"])
def test_beside_another_commands_results_they_stay(w, capsys, argv, rc):
    """A command writing into calibrate's folder leaves its results where and as they are
    (no file of theirs is one it writes)."""
    before = snapshot(w / "cal")
    assert cli(_argv(argv, w), capsys)[0] == rc
    after = snapshot(w / "cal")
    assert {n: after.get(n) for n in before if not n.startswith(".")} == \
        {n: h for n, h in before.items() if not n.startswith(".")}
    assert not (w / "cal" / "previous").exists()
