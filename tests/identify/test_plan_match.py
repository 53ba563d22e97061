"""Photos that do not belong to the session are refused (issue 18 section 3): exit 1, one
line naming the photos and what was seen, nothing calibrated."""

from __future__ import annotations

import pytest

from tests.measure import synth_measure as sm
from vision_cal.commands.main import main


@pytest.fixture(scope="module")
def world():
    sheet = sm.small_sheet()
    targets = sm.free_targets(sheet, 14, rng=33, box=(85.0, 62.0))
    other = sm.free_targets(sheet, 6, rng=34, box=(85.0, 62.0))
    views = [sm.view(tilt_deg=10.0, azimuth_deg=20.0), sm.view(tilt_deg=14.0, azimuth_deg=-70.0)]
    finished = [sm.photo(sheet, sm.texture(sheet, targets, rng=1), K=K, T=T, rng=50 + k)
                for k, (K, T) in enumerate(views)]
    elsewhere = [sm.photo(sheet, sm.texture(sheet, other, rng=2), K=K, T=T, rng=60 + k)
                 for k, (K, T) in enumerate(views)]
    return sheet, targets, finished, elsewhere


def _folder(tmp_path, sheet, q, photos):
    src = tmp_path / "in"
    src.mkdir()
    ids = [f"c{i}" for i in range(len(q))]
    d = sm.session_json(sheet, marks=list(zip(ids, q)), images=[], robot=sm.NOMINAL)
    del d["images"]
    sm.write_session(src, d)
    for k, img in enumerate(photos):
        sm.write_png(src / f"img_{k}.png", img)
    return src


def _run(src, tmp_path, capsys):
    rc = main([str(src), "--out", str(tmp_path / "out"), "--jobs", "1", "-q"])
    err = [ln for ln in capsys.readouterr().err.strip().splitlines() if ln]
    return rc, err


def test_a_pilot_beside_photos_of_a_finished_sheet_is_refused(tmp_path, world, capsys):
    sheet, targets, finished, _ = world
    src = _folder(tmp_path, sheet, sm.plan_for(targets[:3]), finished)   # 3 planned, 14 drawn
    rc, err = _run(src, tmp_path, capsys)
    assert rc == 1 and len(err) == 1, err
    assert "session.json: images: the photos do not match the plan" in err[0]
    assert "img_0.png, img_1.png show 14 dots where 3 planned marks should be" in err[0]
    assert not (tmp_path / "out" / "calibration.json").exists()


def test_dots_that_are_not_where_the_plan_puts_them_are_refused(tmp_path, world, capsys):
    sheet, targets, _, elsewhere = world
    src = _folder(tmp_path, sheet, sm.plan_for(targets[:6]), elsewhere)   # another plan's dots
    rc, err = _run(src, tmp_path, capsys)
    assert rc == 1 and len(err) == 1, err
    assert "the photos do not match the plan: only" in err[0] and "img_0.png, img_1.png" in err[0]


def test_the_photos_of_the_plan_still_calibrate(tmp_path, world, capsys):
    sheet, targets, finished, _ = world
    src = _folder(tmp_path, sheet, sm.plan_for(targets), finished)
    rc, err = _run(src, tmp_path, capsys)
    assert rc == 0, err
