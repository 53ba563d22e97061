"""Never lose a file, never take a wrong number quietly (issue 19): an output that is an
input or another output is refused, a command's outputs are written together or not at
all, odd CSV/JSON/YAML input is refused naming the line, and large inputs are bounded;
each case is exit 2, one line on stderr, and no input or earlier output lost."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tests.commands.test_trust import (PAPER, ROOT, TARGETS, assert_one_line, calibration,  # noqa: F401
                                       cli, dataset, rendered, snapshot)

ROBOT = ROOT / "fixtures" / "robot_sm5.yaml"


@pytest.fixture()
def work(tmp_path, calibration):  # noqa: F811
    """A folder holding a calibration, the targets and the robot file (the inputs)."""
    d = tmp_path / "w"
    d.mkdir()
    shutil.copy(calibration, d / "cal.json")
    shutil.copy(TARGETS, d / "targets.csv")
    shutil.copy(ROBOT, d / "robot.yaml")
    return d


# --------------------------------------------------------------------------- outputs

@pytest.mark.parametrize("argv,field", [
    (["plan", "cal.json", "targets.csv", "-o", "cal.json"], "-o"),
    (["plan", "cal.json", "targets.csv", "-o", "targets.csv"], "-o"),
    (["plan", "cal.json", "targets.csv", "-o", "p.csv", "--trajectory", "cal.json"],
     "--trajectory"),
    (["plan", "cal.json", "targets.csv", "-o", "p.csv", "--trajectory", "p.csv"],
     "--trajectory"),
    (["plan", "cal.json", "targets.csv", "-o", "p.csv", "--trajectory", "p.failed.csv"],
     "--trajectory"),
    (["export", "cal.json", "--yaml", "cal.json"], "--yaml"),
    (["export", "cal.json", "--urdf", "cal.json"], "--urdf"),
    (["export", "cal.json", "--urdf", "x.urdf", "--yaml", "x.urdf"], "--yaml"),
    (["export", "cal.json", "--urdf", "x.urdf", "--yaml", "x.effects.yaml"], "--yaml"),
], ids=["plan-o-cal", "plan-o-targets", "traj-cal", "traj-plan", "traj-failed", "yaml-cal",
        "urdf-cal", "urdf-yaml", "effects-yaml"])
def test_an_output_on_an_input_or_another_output_is_refused(work, capsys, monkeypatch, argv,
                                                            field):
    monkeypatch.chdir(work)
    before = snapshot(work)
    rc, _, err = cli(argv, capsys)
    assert rc == 2
    assert_one_line(err, field, "choose another name")
    assert snapshot(work) == before


def test_a_program_path_that_is_a_folder_writes_nothing(work, capsys):
    (work / "p.prg").mkdir()
    (work / "p.csv").write_text("earlier\n")
    before = snapshot(work)
    rc, _, err = cli(["plan", work / "cal.json", work / "targets.csv", "-o", work / "p.csv",
                      "--program", "spel", "--robot", work / "robot.yaml",
                      "--trajectory", work / "t.csv"], capsys)
    assert rc == 2
    assert_one_line(err, work / "p.prg", "--program")
    assert snapshot(work) == before


def test_outputs_written_together_or_not_at_all(work, capsys, monkeypatch):
    """A failure while writing the last output (the program) leaves the earlier outputs
    of this command unwritten and the files of an earlier run kept, byte for byte, in
    previous/ (nothing that looks current)."""
    import vision_cal.actions.plan as action

    (work / "p.csv").write_text("earlier\n")
    before = snapshot(work)

    def broken(*a, **k):
        from vision_cal.dataset.io import atomic_write_text

        atomic_write_text(work / "p.prg", "half")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(action, "write_program", broken)
    with pytest.raises(OSError):
        cli(["plan", work / "cal.json", work / "targets.csv", "-o", work / "p.csv",
             "--program", "spel", "--robot", work / "robot.yaml", "--trajectory",
             work / "t.csv", "-q", "--force"], capsys)   # --force: the paper's valid_for
    after = snapshot(work)
    assert after.pop("previous/plan-p/p.csv") == before.pop("p.csv")
    assert after == before
    assert not [p for p in work.iterdir() if p.name.endswith(".tmp")]


def test_home_outside_the_joint_limits_is_refused(work, capsys):
    before = snapshot(work)
    rc, _, err = cli(["plan", work / "cal.json", work / "targets.csv", "-o", work / "p.csv",
                      "--home", "300", "0", "--program", "spel", "--robot",
                      work / "robot.yaml"], capsys)
    assert rc == 2
    assert_one_line(err, "--home", "joint 1 at 300 deg", "robot.yaml")
    assert snapshot(work) == before


def test_a_trajectory_too_long_is_refused_before_it_is_built(work, capsys, monkeypatch):
    import vision_cal.plan.trajectory as trajectory

    monkeypatch.setattr(trajectory, "MAX_TRAJECTORY_SAMPLES", 40)  # 3 targets dwell 57
    before = snapshot(work)
    rc, _, err = cli(["plan", work / "cal.json", work / "targets.csv", "-o", work / "p.csv",
                      "--trajectory", work / "t.csv"], capsys)
    assert rc == 2
    assert_one_line(err, work / "t.csv", "--trajectory", "split the targets")
    assert snapshot(work) == before


# --------------------------------------------------------------------------- CSV rows

@pytest.mark.parametrize("text,line,words", [
    ("id,x_mm,y_mm\norigin,0,0\na,100,5,250\n", "line 3", "decimal comma"),
    ('id,x_mm,y_mm\norigin,0,0\na,"100,5\nb,1,2\n', "line 3", "stray quote"),
    ('id,x_mm,y_mm\na,"1,2\n' + "".join(f"b{i},1,2\n" for i in range(12000)), "line 2",
     "stray quote"),
], ids=["decimal-comma", "stray-quote", "stray-quote-over-128KB"])
def test_targets_row_read_wrong_is_refused_naming_the_line(work, capsys, text, line, words):
    t = work / "targets.csv"
    t.write_text(text)
    before = snapshot(work)
    rc, _, err = cli(["plan", work / "cal.json", t, "-o", work / "p.csv"], capsys)
    assert rc == 2
    assert_one_line(err, t, line, words)
    assert snapshot(work) == before


# --------------------------------------------------------------------------- JSON / YAML

def test_duplicate_key_in_session_json_names_both_lines(tmp_path, capsys):
    folder = tmp_path / "data"
    shutil.copytree(PAPER, folder)
    text = (folder / "session.json").read_text()
    s = json.loads(text)
    lines = json.dumps(s, indent=1).splitlines()
    i = next(i for i, ln in enumerate(lines) if ln.startswith(' "format"'))
    lines.insert(i + 1, ' "format": "vision-cal/1",')
    (folder / "session.json").write_text("\n".join(lines))
    before = snapshot(folder)
    rc, _, err = cli([folder, "-o", tmp_path / "out"], capsys)
    assert rc == 2
    assert_one_line(err, folder / "session.json", "'format'", f"lines {i + 1} and {i + 2}")
    assert snapshot(folder) == before and not (tmp_path / "out" / "calibration.json").exists()


def _robot(work, edit) -> Path:
    r = work / "robot.yaml"
    r.write_text(edit(r.read_text()))
    return r


def test_duplicate_key_in_robot_yaml_names_both_lines(work, capsys):
    text = (work / "robot.yaml").read_text()
    i = next(i for i, ln in enumerate(text.splitlines()) if ln.startswith("L1_mm:"))
    r = _robot(work, lambda t: t + "L1_mm: 360.0\n")
    n = len(text.splitlines()) + 1
    before = snapshot(work)
    rc, _, err = cli(["plan", work / "cal.json", work / "targets.csv", "-o", work / "p.csv",
                      "--robot", r], capsys)
    assert rc == 2
    assert_one_line(err, r, "'L1_mm' is given twice", f"lines {i + 1} and {n}")
    assert snapshot(work) == before


def test_yaml_exponent_without_dot_is_a_number(tmp_path):
    from vision_cal.dataset.io import read_yaml

    p = tmp_path / "a.yaml"
    p.write_text("a: 1e5\nb: -2.5E-3\nc: '1e5'\nd: 1.0e+5\ne: 12\n")
    assert read_yaml(p) == {"a": 1e5, "b": -2.5e-3, "c": "1e5", "d": 1e5, "e": 12}


def test_yaml_alias_bomb_is_refused_without_building_it(work, capsys):
    lines = ["a: &a [x, x, x, x, x, x, x, x, x]"]
    for prev, n in zip("abcdefgh", "bcdefghi"):
        lines.append(f"{n}: &{n} [" + ", ".join([f"*{prev}"] * 9) + "]")
    r = work / "robot.yaml"
    r.write_text("\n".join(lines) + "\n")
    before = snapshot(work)
    rc, _, err = cli(["plan", work / "cal.json", work / "targets.csv", "-o", work / "p.csv",
                      "--robot", r], capsys)
    assert rc == 2
    assert_one_line(err, r, "alias bomb")
    assert snapshot(work) == before


def test_a_huge_value_in_an_error_is_cut_before_it_is_printed():
    from vision_cal.dataset.fields import _short

    big = [[list(range(1000))] * 1000] * 1000  # 10^9 numbers if printed whole
    assert len(_short(big)) <= 60


# --------------------------------------------------------------------------- the OUT folder

def _calibrate(capsys, *argv):
    return cli([*argv, "-q"], capsys)


def _results(snap: dict) -> dict:
    """A folder's snapshot without vision-cal's hidden files (its record of the runs)."""
    return {k: v for k, v in snap.items() if not k.startswith(".")}


def _previous(out) -> dict:
    """The earlier calibration kept in OUT/previous/calibrate/."""
    return snapshot(out / "previous" / "calibrate")


def test_a_run_without_report_retires_the_earlier_report(tmp_path, capsys):
    out = tmp_path / "out"
    assert _calibrate(capsys, PAPER, "-o", out, "--report")[0] == 0
    first = snapshot(out)
    rc, _, err = _calibrate(capsys, PAPER, "-o", out)
    assert rc == 0, err
    assert not (out / "report.json").exists() and not (out / "report.html").exists()
    # nothing lost: the earlier set is kept, marked as previous
    assert _previous(out) == {k: v for k, v in first.items()
                              if k in ("calibration.json", "report.json", "report.html")}


def test_a_failed_run_leaves_no_calibration_that_looks_current(tmp_path, capsys):
    out = tmp_path / "out"
    assert _calibrate(capsys, PAPER, "-o", out, "--report")[0] == 0
    first = snapshot(out)
    bad = tmp_path / "bad"
    shutil.copytree(PAPER, bad)
    s = json.loads((bad / "session.json").read_text())
    s["marks"] = s["marks"][:2]  # too few marks: cannot calibrate (exit 1)
    s.pop("images", None)
    (bad / "session.json").write_text(json.dumps(s))
    rc, _, err = _calibrate(capsys, bad, "-o", out)
    assert rc == 1
    assert_one_line(err, "at least 3")
    assert not (out / "calibration.json").exists() and not (out / "report.html").exists()
    assert _previous(out) == _results(first)


def test_ctrl_c_while_the_report_is_written_leaves_no_report(tmp_path, capsys, monkeypatch):
    import vision_cal.report.html as html

    out = tmp_path / "out"
    assert _calibrate(capsys, PAPER, "-o", out, "--report")[0] == 0
    first = snapshot(out)

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(html, "render_html", interrupted)
    rc, _, err = _calibrate(capsys, PAPER, "-o", out, "--report")
    assert rc == 130
    assert_one_line(err, "interrupted")
    assert not (out / "report.json").exists() and not (out / "report.html").exists()
    assert _previous(out) == _results(first)


def test_two_folders_with_one_name_get_their_own_outputs(tmp_path, capsys):
    for day in ("day1", "day2"):
        shutil.copytree(PAPER, tmp_path / day / "plan")
    s = json.loads((tmp_path / "day2" / "plan" / "session.json").read_text())
    s["marks"] = s["marks"][:-1]  # day 2 is a different session
    (tmp_path / "day2" / "plan" / "session.json").write_text(json.dumps(s))
    out = tmp_path / "B"
    rc, _, err = cli([tmp_path / "day1" / "plan", tmp_path / "day2" / "plan", "--out", out],
                     capsys)
    assert rc == 0, err
    summary = json.loads((out / "summary.json").read_text())["folders"]
    outs = [r["out"] for r in summary]
    assert outs == [str(out / "day1-plan" / "calibration.json"),
                    str(out / "day2-plan" / "calibration.json")]
    docs = [json.loads(Path(o).read_text()) for o in outs]
    assert len(docs[0]["marks"]) == len(docs[1]["marks"]) + 1


def test_the_same_folder_twice_is_refused(tmp_path, capsys):
    rc, _, err = cli([PAPER, f"{PAPER}/", "--out", tmp_path / "B"], capsys)
    assert rc == 2
    assert_one_line(err, "DIR", "given twice")
    assert not (tmp_path / "B").exists()


# --------------------------------------------------------------------------- implausible fits

@pytest.mark.parametrize("unit,words", [("rad", "radians"), ("m", "metres")])
def test_a_unit_mistake_stops_the_run_naming_it(tmp_path, capsys, unit, words):
    """Joints in radians (the fit reaches L1 ~ 60x nominal), or the robot block in metres:
    exit 2, one line naming session.json and the likely mistake, no calibration.json, the
    earlier results kept under previous/."""
    import math

    def edit(s):
        if unit == "rad":
            for m in s["marks"]:
                m["joints_deg"] = [math.radians(v) for v in m["joints_deg"]]
        else:
            r = s["robot"]
            r["L1_mm"], r["L2_mm"] = r["L1_mm"] / 1000, r["L2_mm"] / 1000

    from tests.commands.test_trust import dataset

    folder = dataset(tmp_path, edit)
    out = tmp_path / "out"
    assert _calibrate(capsys, PAPER, "-o", out)[0] == 0
    first = snapshot(out)
    before = snapshot(folder)
    rc, _, err = _calibrate(capsys, folder, "-o", out)
    assert rc == 2
    assert_one_line(err, folder / "session.json", "implausible", words)
    assert not (out / "calibration.json").exists() and _previous(out) == _results(first)
    assert snapshot(folder) == before


@pytest.mark.parametrize("size", ["1e6", "1e7", "5001"])
def test_a_custom_sheet_beyond_any_work_area_is_refused(tmp_path, capsys, size):
    out = tmp_path / "s"
    rc, _, err = cli(["sheet", "--custom", size, "300", "--out", out], capsys)
    assert rc == 2
    assert_one_line(err, "--custom", "at most 5000 mm")
    assert not out.exists()


def test_a_wrong_declared_lens_is_blamed_on_camera_dist(tmp_path, capsys, rendered):  # noqa: F811
    """Issue 19: k1 = 0.5 declared for a lens without distortion: the markers fit the sheet
    without it, so the line names camera.dist, not sheet.markers."""
    truth = json.loads((rendered / "truth.json").read_text())

    def edit(s):
        cam = s.get("camera") or {"size_px": truth["camera"]["size_px"], "K": truth["camera"]["K"]}
        cam["dist"] = [0.5, 0.0, 0.0, 0.0, 0.0]
        s["camera"] = cam

    folder = dataset(tmp_path, edit, src=rendered)
    before = snapshot(folder)
    rc, _, err = cli([folder, "-o", tmp_path / "out", "-j", "1"], capsys)
    assert rc == 2
    line = assert_one_line(err, folder / "session.json", "camera.dist", "lens distortion")
    assert "sheet.markers" not in line
    assert snapshot(folder) == before and not (tmp_path / "out" / "calibration.json").exists()
