"""Trust at the boundaries (issue 11): every bad input is one line naming the file and the
field, exit 2, no traceback, nothing written into the input folder; no silently wrong
answer from a sheet typed wrong, a sheet frame with its origin elsewhere, or a calibration
file that lies."""

from __future__ import annotations

import errno
import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from vision_cal.commands.main import main

ROOT = Path(__file__).resolve().parents[2]
PAPER = ROOT / "fixtures" / "paper_sm5"
TARGETS = ROOT / "fixtures" / "targets_origin.csv"


# --------------------------------------------------------------------------- helpers

def snapshot(folder: Path) -> dict:
    """Every file under ``folder``: its content hash (to prove nothing was written)."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def cli(argv, capsys) -> tuple[int, str, str]:
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as e:  # argparse
        rc = e.code
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "Traceback" not in out
    return rc, out, err


def assert_one_line(err: str, *names: str) -> str:
    """Exactly one line on stderr, naming each of ``names`` (file, field; a name starting
    with "-" is a command-line option, looked for as ": -o:")."""
    from vision_cal.progress import PREFIX

    lines = [ln for ln in err.strip().splitlines() if not ln.startswith(PREFIX)]
    assert len(lines) == 1, err
    for n in names:
        n = f": {n}:" if str(n).startswith("-") else str(n)
        assert n in lines[0], (n, lines[0])
    return lines[0]


def dataset(tmp_path: Path, edit, src: Path = PAPER, name: str = "data") -> Path:
    """A copy of the dataset ``src`` with its session.json edited by ``edit(dict)``."""
    folder = tmp_path / name
    shutil.copytree(src, folder)
    s = json.loads((folder / "session.json").read_text())
    edit(s)
    (folder / "session.json").write_text(json.dumps(s))
    return folder


@pytest.fixture(scope="module")
def calibration(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("cal")
    assert main([str(PAPER), "-o", str(out), "-q"]) == 0
    return out / "calibration.json"


def bad_calibration(tmp_path, calibration, edit) -> Path:
    doc = json.loads(calibration.read_text())
    edit(doc)
    p = tmp_path / "in" / "calibration.json"
    p.parent.mkdir(exist_ok=True)
    p.write_text(json.dumps(doc))
    return p


# --------------------------------------------------------------------------- session.json

def _set(path, value):
    def edit(s):
        o = s
        for k in path[:-1]:
            o = o[k]
        o[path[-1]] = value
    return edit


@pytest.mark.parametrize("edit,field", [
    (_set(("pen", "mark_diameter_mm"), -2), "pen.mark_diameter_mm"),
    (_set(("pen", "mark_diameter_mm"), 0), "pen.mark_diameter_mm"),
    (lambda s: s["marks"][0].__setitem__("joints_deg", [1e308, 0.0]), "marks[0].joints_deg[0]"),
    (_set(("robot", "L1_mm"), 10**400), "robot.L1_mm"),
    (_set(("camera",), {"size_px": [640, 480], "K": [[0, 0, 0], [0, 0, 0], [0, 0, 0]],
                        "dist": [0, 0, 0, 0, 0]}), "camera.K[0][0]"),
], ids=["pen-negative", "pen-zero", "joints-1e308", "L1-huge-int", "K-zero"])
def test_bad_session_field_is_one_line_exit_2(tmp_path, capsys, edit, field):
    folder = dataset(tmp_path, edit)
    before = snapshot(folder)
    rc, _, err = cli([folder, "-o", tmp_path / "out"], capsys)
    assert rc == 2
    assert_one_line(err, folder / "session.json", field)
    assert snapshot(folder) == before
    assert not (tmp_path / "out" / "calibration.json").exists()


def test_json_nested_200000_deep_is_one_line(tmp_path, capsys):
    folder = tmp_path / "deep"
    folder.mkdir()
    (folder / "session.json").write_text("[" * 200_000 + "]" * 200_000)
    rc, _, err = cli([folder, "-o", tmp_path / "out"], capsys)
    assert rc == 2
    assert "nested too deeply" in assert_one_line(err, folder / "session.json")
    assert snapshot(folder) == {"session.json": snapshot(folder)["session.json"]}


def test_session_saved_with_bom_is_read(tmp_path, capsys):
    folder = dataset(tmp_path, lambda s: None)
    p = folder / "session.json"
    p.write_bytes(b"\xef\xbb\xbf" + p.read_bytes().replace(b"\n", b"\r\n"))
    before = snapshot(folder)
    rc, _, err = cli([folder, "-o", tmp_path / "out", "-q"], capsys)
    assert rc == 0, err
    assert snapshot(folder) == before


# --------------------------------------------------------------------------- outputs

def test_out_that_is_a_file(tmp_path, capsys):
    f = tmp_path / "out"
    f.write_text("not a folder")
    before = snapshot(PAPER)
    rc, _, err = cli([PAPER, "-o", f], capsys)
    assert rc == 2
    assert_one_line(err, f, "--out")
    assert f.read_text() == "not a folder" and snapshot(PAPER) == before


def test_out_on_a_read_only_file_system(tmp_path, capsys, monkeypatch):
    """What the kernel says on a read-only mount (root passes chmod, so it is simulated
    at the two places the code asks the file system)."""
    import os

    from vision_cal.dataset import io as vio

    ro = tmp_path / "ro"
    ro.mkdir()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, m, **k: False if Path(p) == ro
                        else real_access(p, m, **k))
    monkeypatch.setattr(vio, "_read_only", lambda p: Path(p) == ro)
    rc, _, err = cli([PAPER, "-o", ro / "out"], capsys)
    assert rc == 2
    assert "read-only file system" in assert_one_line(err, ro / "out", "--out")
    assert list(ro.iterdir()) == []


@pytest.mark.parametrize("call", ["tempfile.mkstemp", "os.replace"])
def test_write_failure_midway_is_one_line(tmp_path, capsys, monkeypatch, calibration, call):
    """An OSError from the file system while writing (EROFS after the checks passed),
    when the temporary file is made or when it is renamed into place."""
    import importlib

    def refuse(*a, **k):
        raise OSError(errno.EROFS, "Read-only file system")

    mod, name = call.split(".")
    monkeypatch.setattr(importlib.import_module(mod), name, refuse)
    rc, _, err = cli(["plan", calibration, TARGETS, "-o", tmp_path / "plan.csv", "--force"],
                     capsys)
    assert rc == 2
    assert "read-only file system" in assert_one_line(err, tmp_path / "plan.csv")
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no temporary file left


def test_plan_out_is_a_folder(tmp_path, capsys, calibration):
    rc, _, err = cli(["plan", calibration, TARGETS, "-o", tmp_path], capsys)
    assert rc == 2
    assert_one_line(err, tmp_path, "-o")


def test_export_into_a_path_under_a_file(tmp_path, capsys, calibration):
    f = tmp_path / "file"
    f.write_text("x")
    rc, _, err = cli(["export", calibration, "--yaml", f / "cal.yaml"], capsys)
    assert rc == 2
    assert_one_line(err, f / "cal.yaml", "--yaml")
    assert f.read_text() == "x"


def test_targets_saved_by_excel_as_csv_utf8(tmp_path, capsys, calibration):
    t = tmp_path / "targets.csv"
    t.write_bytes(b"\xef\xbb\xbfid,x_mm,y_mm\r\norigin,0,0\r\np1,50,-150\r\n")
    rc, _, err = cli(["plan", calibration, t, "-o", tmp_path / "plan.csv", "-q", "--force"],
                     capsys)
    assert rc == 0, err
    from vision_cal.dataset.csvio import read_plan

    ids, q, _ = read_plan(tmp_path / "plan.csv")
    assert ids == ["origin", "p1"] and np.isfinite(q).all()


# --------------------------------------------------------------------------- calibration.json

@pytest.mark.parametrize("edit,field", [
    (lambda d: d["params"].__setitem__("L2_mm", -260.0), "params.L2_mm"),
    (lambda d: d.__setitem__("effects", {"name": "joint_backlash", "joint": 2, "deg": 0.1}),
     "effects"),
    (lambda d: d["params"].__setitem__("L1_mm", float("nan")), "params.L1_mm"),
    (lambda d: d["params"].__setitem__("joint_zero_deg", [0.0]), "params.joint_zero_deg"),
    (lambda d: d.__setitem__("effects", [{"name": "joint_backlash", "joint": 3, "deg": 0.1}]),
     "effects[0].joint"),
    (lambda d: d.__setitem__("effects", [{"name": "joint_backlsh", "joint": 2, "deg": 0.1}]),
     "effects[0].name"),
], ids=["L2-negative", "effects-object", "L1-nan", "zero-short", "joint-3", "unknown-name"])
def test_plan_refuses_a_bad_calibration(tmp_path, capsys, calibration, edit, field):
    cal = bad_calibration(tmp_path, calibration, edit)
    before = snapshot(cal.parent)
    rc, _, err = cli(["plan", cal, TARGETS, "-o", tmp_path / "plan.csv"], capsys)
    assert rc == 2
    assert_one_line(err, cal, field)
    assert not (tmp_path / "plan.csv").exists() and snapshot(cal.parent) == before


def test_plan_nothing_plannable_exits_1_and_writes_no_nan(tmp_path, capsys, calibration):
    cal = bad_calibration(tmp_path, calibration,
                          lambda d: d["params"].__setitem__("base_mm", [5000.0, 5000.0]))
    out = tmp_path / "plan.csv"
    rc, _, err = cli(["plan", cal, TARGETS, "-o", out], capsys)
    assert rc == 1
    assert_one_line(err, TARGETS, "3 out of reach")
    assert out.read_text().splitlines() == ["id,q1_deg,q2_deg,approach1,approach2"]
    failed = (tmp_path / "plan.failed.csv").read_text().splitlines()
    assert failed[0] == "id,x_mm,y_mm,reason" and len(failed) == 4


def test_plan_failures_are_summarised_not_listed(tmp_path, capsys, calibration):
    rng = np.random.default_rng(0)
    xy = rng.uniform(-2000, 2000, (3000, 2))
    t = tmp_path / "many.csv"
    t.write_text("id,x_mm,y_mm\n" + "".join(f"t{i},{x},{y}\n" for i, (x, y) in enumerate(xy)))
    out = tmp_path / "plan.csv"
    rc, _, err = cli(["plan", calibration, t, "-o", out, "-q", "--force"], capsys)
    assert rc == 3   # partial: planned in part
    # the targets planned beyond the marks' joints (valid_for, --force) in a line of their own
    beyond = [ln for ln in err.splitlines() if "outside the joints the calibration" in ln]
    assert len(beyond) == 1 and "more" in beyond[0], err
    line = assert_one_line("\n".join(ln for ln in err.splitlines() if ln not in beyond), t,
                           "not planned", "more")
    n_failed = int(line.split(f"{t}: ")[1].split()[0])
    rows = out.read_text().splitlines()
    assert "nan" not in out.read_text().lower()
    failed = (tmp_path / "plan.failed.csv").read_text().splitlines()
    assert len(rows) - 1 + len(failed) - 1 == 3000 and len(failed) - 1 == n_failed


# --------------------------------------------------------------------------- rendered photos

@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """One small rendered dataset (the end-to-end suite's scene), edited per test."""
    from tests.test_end_to_end import ds, pilot_params, scene

    return ds.render_dataset(scene(seed=12), tmp_path_factory.mktemp("render") / "data",
                             pilot=pilot_params)


def _markers(edit_corners):
    def edit(s):
        for m in s["sheet"]["markers"]:
            m["corners_mm"] = np.asarray(edit_corners(np.asarray(m["corners_mm"], float))).tolist()
    return edit


def _resize(c, f):
    return c.mean(axis=0) + (c - c.mean(axis=0)) * f


@pytest.mark.parametrize("edit,cause", [
    (_markers(lambda c: c[::-1]), "corner order"),
    (_markers(lambda c: _resize(c, 0.9)), "marker size: printed about 30.0 mm, declared 27.0 mm"),
], ids=["reverse-order", "27-for-30"])
def test_sheet_typed_wrong_stops_naming_sheet_markers(tmp_path, capsys, rendered, edit, cause):
    folder = dataset(tmp_path, edit, src=rendered)
    before = snapshot(folder)
    rc, _, err = cli([folder, "-o", tmp_path / "out", "-j", "1"], capsys)
    assert rc == 2
    line = assert_one_line(err, folder / "session.json", "sheet.markers", "corner RMS", cause)
    assert snapshot(folder) == before
    assert not (tmp_path / "out" / "calibration.json").exists()
    # the tolerance printed is the derived one: 1 % of a 30 mm side plus 2 pixels of this
    # render (0.65 mm/px: 1.6 mm), under what the typing mistake leaves
    assert float(line.split("explain ")[1].split(" mm")[0]) < 0.3 + 2.0 * 0.7


def test_printer_scale_of_one_percent_still_calibrates(tmp_path, capsys, rendered):
    """The declared sheet 1 % larger along x than printed (a printer's uneven scale): an
    affine map, which the mapping absorbs; every photo stays ok."""
    folder = dataset(tmp_path, _markers(lambda c: c * [1.01, 1.0]), src=rendered)
    rc, _, err = cli([folder, "-o", tmp_path / "out", "-j", "1", "-q"], capsys)
    assert rc == 0, err
    doc = json.loads((tmp_path / "out" / "calibration.json").read_text())
    assert all(im["status"] == "ok" for im in doc["images"])
    aff = [e for e in doc["effects"] if e["name"] == "sheet_affine"]
    assert aff and aff[0]["matrix"][0][0] == pytest.approx(1.01, abs=0.002)


def test_sheet_origin_elsewhere_calibrates_the_same(tmp_path, capsys, rendered):
    """The same sheet with its frame's origin 1000 mm right and 500 mm down (every marker
    corner and the nominal base shifted, no bottom_left_mm): the same robot, its base
    shifted by the same constant."""
    off = np.array([1000.0, -500.0])

    def shift(s):
        _markers(lambda c: c + off)(s)
        s["sheet"].pop("bottom_left_mm", None)
        s["robot"]["base_mm"] = (np.asarray(s["robot"]["base_mm"]) + off).tolist()

    a = dataset(tmp_path, lambda s: s["sheet"].pop("bottom_left_mm", None), src=rendered,
                name="a")
    b = dataset(tmp_path, shift, src=rendered, name="b")
    assert cli([a, "-o", tmp_path / "oa", "-j", "1", "-q"], capsys)[0] == 0
    rc, _, err = cli([b, "-o", tmp_path / "ob", "-j", "1", "-q"], capsys)
    assert rc == 0, err
    pa = json.loads((tmp_path / "oa" / "calibration.json").read_text())["params"]
    pb = json.loads((tmp_path / "ob" / "calibration.json").read_text())["params"]
    assert pb["L1_mm"] == pytest.approx(pa["L1_mm"], abs=1e-3)
    assert pb["L2_mm"] == pytest.approx(pa["L2_mm"], abs=1e-3)
    assert np.allclose(pb["joint_zero_deg"], pa["joint_zero_deg"], atol=1e-4)
    assert np.allclose(np.subtract(pb["base_mm"], pa["base_mm"]), off, atol=1e-3)


def test_wrong_dictionary_names_the_cause(tmp_path, capsys, rendered):
    folder = dataset(tmp_path, lambda s: s["sheet"].__setitem__("aruco_dictionary",
                                                                 "DICT_4X4_50"), src=rendered)
    rc, _, err = cli([folder, "-o", tmp_path / "out", "-j", "1"], capsys)
    assert rc == 1
    assert_one_line(err, "0 calibration marks", "1 of 1 photos skipped", "1 wrong sheet",
                    "DICT_5X5")


def test_ctrl_c_after_the_photos_are_measured_leaves_nothing_that_looks_current(
        tmp_path, capsys, rendered, monkeypatch):
    """Issue 30: a run stopped between measuring and fitting left a new measurement.json
    beside the earlier calibration (moved to previous/). measurement.json is now renamed
    into OUT with calibration.json at the end; the detection cache is kept."""
    import vision_cal.actions.pipeline as pipeline

    folder = dataset(tmp_path, lambda s: None, src=rendered)
    out = tmp_path / "out"
    out.mkdir()
    for n in ("calibration.json", "measurement.json"):
        (out / n).write_text(json.dumps({"earlier": n}))
    earlier = snapshot(out)
    measured = []
    real = pipeline.measure_marks

    def spy(*a, **k):
        r = real(*a, **k)
        measured.append(r[0])
        return r

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline, "measure_marks", spy)
    monkeypatch.setattr(pipeline, "fit_marks", interrupted)
    rc, _, _ = cli([folder, "-o", out, "-j", "1", "-q"], capsys)
    assert rc == 130
    assert measured and measured[0] is not None      # the photos were measured, then Ctrl-C
    left = snapshot(out)
    current = [n for n in left if not n.startswith(("previous/", ".cache/"))]
    assert current == [], current
    # written by hand here (no record of the run that wrote them): previous/unrecorded/
    assert {n: left[f"previous/unrecorded/{n}"] for n in ("calibration.json",
                                                          "measurement.json")} \
        == earlier
    assert any(n.startswith(".cache/") for n in left)  # kept: the next run measures nothing
