"""Files that are what they look like (issue 38): a command's output set is replaced as a
whole, what an earlier run wrote and this one does not moved to previous/ with the rest;
two inputs never share one output; a column named twice is refused by every CSV reader; a
lock path that is a folder is one line."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from tests.commands.test_never_lose import work  # noqa: F401
from tests.commands.test_trust import (PAPER, ROOT, assert_one_line, calibration,  # noqa: F401
                                       cli, snapshot)
from vision_cal.dataset.out_folder import LOCK, RECORD
from vision_cal.errors import VisionCalError

ROBOT = ROOT / "fixtures" / "robot_sm5.yaml"
TRACKER = ROOT / "fixtures" / "tracker_example"


def _current(snap: dict) -> dict:
    """What looks current in a folder: not previous/, not vision-cal's hidden files."""
    return {n: h for n, h in snap.items() if not n.startswith(("previous/", "."))
            and "/." not in n}


# --------------------------------------------------------------------------- plan

def test_a_plan_that_plans_nothing_leaves_no_earlier_program_or_trajectory(  # noqa: F811
        work, capsys):
    """It left the earlier run's .mod and trajectory beside a header-only CSV."""
    (work / "far.csv").write_text("id,x_mm,y_mm\nfar,5000,5000\n")
    first = ["plan", work / "cal.json", work / "targets.csv", "-o", work / "p.csv",
             "--program", "rapid", "--robot", work / "robot.yaml", "--trajectory",
             work / "t.csv", "--force", "-q"]
    assert cli(first, capsys)[0] == 3   # "far" out of reach: in part
    earlier = snapshot(work)
    assert {"p.csv", "p.mod", "t.csv"} <= set(earlier)
    rc, _, err = cli(["plan", work / "cal.json", work / "far.csv", "-o", work / "p.csv",
                      "--program", "rapid", "--robot", work / "robot.yaml", "--trajectory",
                      work / "t.csv", "--force", "-q"], capsys)
    assert rc == 1 and "nothing could be planned" in err
    after = snapshot(work)
    assert not (work / "p.mod").exists() and not (work / "t.csv").exists()
    for n in ("p.csv", "p.mod", "t.csv"):   # the earlier set, whole, byte for byte
        assert after[f"previous/plan-p/{n}"] == earlier[n], n
    # the next run moves this one's (the header and the failed targets) aside in its turn
    empty = {n: after[n] for n in ("p.csv", "p.failed.csv")}
    assert cli(first, capsys)[0] == 3   # "far" out of reach: in part
    again = snapshot(work)
    assert {n: again[f"previous/plan-p/{n}"] for n in empty} == empty
    assert not [n for n in again if n.startswith("previous/") and "plan-p" not in n]


def test_a_plan_in_another_dialect_moves_the_earlier_program_aside(work, capsys):  # noqa: F811
    base = ["plan", work / "cal.json", work / "targets.csv", "-o", work / "p.csv", "--robot",
            work / "robot.yaml", "--force", "-q", "--program"]
    assert cli([*base, "val3"], capsys)[0] == 3   # in part: "far"
    app = {f.relative_to(work).as_posix(): f.read_bytes()   # the VAL3 application folder p/
           for f in (work / "p").rglob("*") if f.is_file()}
    assert "p/p.pjx" in app
    assert cli([*base, "spel"], capsys)[0] == 3
    assert (work / "p.prg").is_file() and not (work / "p").exists()
    for n, data in app.items():
        assert (work / "previous" / "plan-p" / n).read_bytes() == data, n


def test_two_plans_in_one_folder_keep_their_own_previous(work, capsys):  # noqa: F811
    """previous/ never drops another output set's result: each plan has its own."""
    for out in ("a.csv", "b.csv", "a.csv", "b.csv"):
        assert cli(["plan", work / "cal.json", work / "targets.csv", "-o", work / out,
                    "--force", "-q"], capsys)[0] == 3   # in part: "far"
    assert (work / "previous" / "plan-a" / "a.csv").is_file()
    assert (work / "previous" / "plan-b" / "b.csv").is_file()


# --------------------------------------------------------------------------- design

def test_a_design_in_another_dialect_leaves_no_earlier_program(tmp_path, calibration,  # noqa: F811
                                                               capsys, monkeypatch):
    """design --program spel over a folder designed with --program val3 left the old
    program.pgx driving the old marks beside the new session.json (no previous/)."""
    import vision_cal.design.stage as stage

    monkeypatch.setattr(stage, "preview_png", lambda *a, **k: b"\x89PNG a preview")  # cheap
    assert cli(["sheet", "--size", "A4", "--out", tmp_path / "sheet", "-q"], capsys)[0] == 0
    argv = ["design", ROBOT, "--sheet", tmp_path / "sheet" / "sheet.json", "--verify",
            calibration, "--out", tmp_path / "plan", "-q", "--program"]
    assert cli([*argv, "val3"], capsys)[0] == 0
    earlier = snapshot(tmp_path / "plan")
    assert cli([*argv, "spel", "--seed", "7"], capsys)[0] == 0
    after = snapshot(tmp_path / "plan")
    assert set(_current(after)) == {"session.json", "program.prg", "trajectory.csv",
                                    "preview.png"}
    for n, h in _current(earlier).items():   # the VAL3 application program/ among them
        assert after[f"previous/design/{n}"] == h, n
    assert "program/program.pjx" in earlier
    assert not (tmp_path / "plan" / "program").exists()


# --------------------------------------------------------------------------- calibrate

def _marks_csv(path: Path, drop: int = 0) -> Path:
    """The tracker example's marks (the last ``drop`` of them left out: another session)."""
    lines = (TRACKER / "marks.csv").read_text().splitlines()
    path.write_text("\n".join(lines[:len(lines) - drop]) + "\n")
    return path


def test_several_folders_again_replace_the_whole_set(tmp_path, capsys):
    """calibrate a.csv b.csv --out X then a.csv c.csv --out X replaced X/summary.json
    without previous/ and left X/b/ beside it."""
    a, b, c = (_marks_csv(tmp_path / f"{n}.csv", drop=i) for i, n in enumerate("abc"))
    x = tmp_path / "X"
    robot = ["--robot", TRACKER / "robot.yaml", "-q"]
    assert cli(["calibrate", a, b, "--out", x, *robot], capsys)[0] == 0
    earlier = snapshot(x)
    assert cli(["calibrate", a, c, "--out", x, *robot], capsys)[0] == 0
    after = snapshot(x)
    current = set(_current(after))
    assert {"summary.json", "a/calibration.json", "c/calibration.json"} <= current
    assert all(n == "summary.json" or n.startswith(("a/", "c/")) for n in current), current
    assert not (x / "b").exists()
    for n, h in _current(earlier).items():   # summary.json and b/ among them
        assert after[f"previous/calibrate/{n}"] == h, n
    rows = json.loads((x / "summary.json").read_text())["folders"]
    assert [Path(r["folder"]).name for r in rows] == ["a.csv", "c.csv"]


def test_a_marks_csv_and_a_folder_of_one_name_get_two_outputs(tmp_path, capsys):
    """calibrate marks.csv other/marks/ sent both to X/marks."""
    _marks_csv(tmp_path / "marks.csv")
    shutil.copytree(PAPER, tmp_path / "other" / "marks")
    x = tmp_path / "X"
    rc, _, err = cli(["calibrate", tmp_path / "marks.csv", tmp_path / "other" / "marks",
                      "--robot", TRACKER / "robot.yaml", "--out", x, "-q"], capsys)
    assert rc == 0, err
    outs = [r["out"] for r in json.loads((x / "summary.json").read_text())["folders"]]
    assert len(set(outs)) == 2 and all(Path(o).is_file() for o in outs)
    docs = [json.loads(Path(o).read_text()) for o in outs]
    assert len(docs[0]["marks"]) != len(docs[1]["marks"])


def test_a_marks_csv_beside_a_folder_of_its_name(tmp_path, capsys):
    _marks_csv(tmp_path / "marks.csv")
    shutil.copytree(PAPER, tmp_path / "marks")
    x = tmp_path / "X"
    assert cli(["calibrate", tmp_path / "marks.csv", tmp_path / "marks", "--robot",
                TRACKER / "robot.yaml", "--out", x, "-q"], capsys)[0] == 0
    assert (x / "marks" / "calibration.json").is_file()
    assert (x / "marks.csv" / "calibration.json").is_file()


def test_several_folders_into_one_of_them_are_refused_before_any(tmp_path, capsys):
    for n in ("a", "b"):
        shutil.copytree(PAPER, tmp_path / n)
    before = snapshot(tmp_path)
    rc, _, err = cli(["calibrate", tmp_path / "a", tmp_path / "b", "--out", tmp_path], capsys)
    assert rc == 2
    assert_one_line(err, "--out", "is the input DIR")
    assert snapshot(tmp_path) == before


# --------------------------------------------------------------------------- the lock

@pytest.mark.parametrize("name", [LOCK, RECORD])
def test_a_lock_or_record_path_that_is_a_folder_is_one_line(tmp_path, capsys, name):
    out = tmp_path / "o"
    (out / name).mkdir(parents=True)
    before = snapshot(tmp_path)
    rc, _, err = cli(["calibrate", PAPER, "--out", out], capsys)
    assert rc == 2
    assert_one_line(err, out / name, "is a folder", "remove it")
    assert snapshot(tmp_path) == before and (out / name).is_dir()


# --------------------------------------------------------------------------- CSV columns

def _csv_readers(tmp_path):
    """Every CSV reader of the package: (name, reader of a path)."""
    from vision_cal.actions.locate import _read_pixels
    from vision_cal.camera.poses_file import read_poses
    from vision_cal.dataset.csvio import read_plan, read_target_theta, read_targets
    from vision_cal.dataset.marks_csv import session_from_marks_csv
    from vision_cal.world.rehearse import program_moves

    return [
        ("targets", "id,x_mm,y_mm,x_mm\nt1,100,200,0\n", read_targets),
        ("theta", "id,x_mm,y_mm,theta_deg,theta_deg\nt1,1,2,3,4\n", read_target_theta),
        ("plan", "id,q1_deg,q2_deg,approach1,approach2,q1_deg\na,1,2,1,1,0\n", read_plan),
        ("marks", (TRACKER / "marks.csv").read_text().replace("x_mm,y_mm", "x_mm,x_mm", 1),
         lambda p: session_from_marks_csv(p, TRACKER / "robot.yaml")),
        ("pixels", "id,u_px,v_px,u_px\na,1,2,3\n", lambda p: _read_pixels(p, 0.0)),
        ("poses", "id,u_px,u_px\na,1,2\n", read_poses),
        ("points", "kind,j1_deg,j2_deg,j1_deg\nhome,0,0,0\n",
         lambda p: program_moves(p, pen_down_mm=-10.0)),
    ]


def test_every_csv_reader_refuses_a_column_named_twice(tmp_path):
    """A duplicated column silently took the last one (a target planned at the wrong x; a
    marks CSV with every x 0): refused naming the file and the column."""
    for name, text, read in _csv_readers(tmp_path):
        path = tmp_path / f"{name}.csv"
        path.write_text(text)
        with pytest.raises(VisionCalError) as e:
            read(path)
        assert str(path) in str(e.value) and "given twice" in str(e.value), name
        assert "line 1" in str(e.value), name


def test_plan_with_a_column_named_twice_is_one_line(work, capsys):  # noqa: F811
    (work / "dup.csv").write_text("id,x_mm,y_mm,x_mm\nt1,100,200,0\n")
    before = snapshot(work)
    rc, _, err = cli(["plan", work / "cal.json", work / "dup.csv", "-o", work / "p.csv"],
                     capsys)
    assert rc == 2
    assert_one_line(err, work / "dup.csv", "'x_mm' is given twice (columns 2 and 4)")
    assert snapshot(work) == before


def test_no_module_reads_csv_but_the_csv_owner():
    """One CSV reader (dataset/csvio.py): csv.reader or csv.DictReader anywhere else would
    take a column named twice silently."""
    pkg = ROOT / "vision_cal"
    found = [str(f.relative_to(pkg)) for f in pkg.rglob("*.py")
             if re.search(r"\bcsv\.(reader|DictReader)\b", f.read_text())
             and f.relative_to(pkg).as_posix() != "dataset/csvio.py"]
    assert found == []
