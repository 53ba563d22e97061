"""Batch: bad photos are skipped with a reason, the rest measured; cache; read-only input."""

from __future__ import annotations

import logging
import os
import stat
from dataclasses import replace

import cv2
import numpy as np
import pytest

from tests.measure import synth_measure as sm
from vision_cal.dataset.session import Session, load_session
from vision_cal.errors import VisionCalError
from vision_cal.measure import detect, types
from vision_cal.measure.detect import _drop_deformed_markers, detect_image_bytes
from vision_cal.actions.measure_folder import measure_folder


@pytest.fixture(scope="module")
def world():
    sheet = sm.small_sheet()
    targets = sm.free_targets(sheet, 8, rng=21, box=(85.0, 62.0))
    q = sm.plan_for(targets)
    tex = sm.texture(sheet, targets, rng=1)
    K, T = sm.view(tilt_deg=10.0, azimuth_deg=60.0)
    good = sm.photo(sheet, tex, K=K, T=T, rng=2)
    K2, T2 = sm.view(tilt_deg=14.0, azimuth_deg=-70.0)
    good2 = sm.photo(sheet, tex, K=K2, T=T2, rng=3)
    other = sm.small_sheet("DICT_4X4_50")
    wrong = sm.photo(other, sm.texture(other, targets, rng=1), K=K, T=T, rng=4)
    # most of the sheet hidden: only one column of markers left
    few = good.copy()
    few[:, 300:] = (90, 90, 90)
    return sheet, targets, q, good, good2, wrong, few


def _write(folder, world, files):
    sheet, targets, q, *_ = world
    ids = [f"c{i}" for i in range(len(targets))]
    sm.write_session(folder, sm.session_json(
        sheet, marks=list(zip(ids, q)), images=[(f, ids) for f in files], robot=sm.NOMINAL))


def test_bad_photos_are_skipped_with_a_reason(tmp_path, world, caplog):
    sheet, targets, q, good, good2, wrong, few = world
    src = tmp_path / "in"
    src.mkdir()
    sm.write_png(src / "good.png", good)
    sm.write_png(src / "good2.png", good2)
    data = (src / "good.png").read_bytes()
    (src / "truncated.png").write_bytes(data[: len(data) // 2])
    (src / "text.png").write_bytes(b"this is not an image\n" * 20)
    sm.write_png(src / "blank.png", np.full((750, 1000, 3), 128, np.uint8))
    sm.write_png(src / "wrong.png", wrong)
    sm.write_png(src / "few.png", few)
    sm.write_png(src / "stray.png", good)       # in the folder, not in session.json
    files = ["good.png", "missing.png", "truncated.png", "text.png", "blank.png",
             "wrong.png", "few.png", "good2.png"]
    _write(src, world, files)
    before = {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in src.iterdir()}
    # the input folder is read-only: nothing may be written there
    for p in src.iterdir():
        p.chmod(stat.S_IRUSR)
    src.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        with caplog.at_level(logging.WARNING):
            meas = measure_folder(load_session(src), out_dir=tmp_path / "out", jobs=2)
    finally:
        src.chmod(stat.S_IRWXU)
    after = {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in src.iterdir()}
    assert after == before
    st = {im.file: im for im in meas.images}
    assert [im.file for im in meas.images] == files
    reasons = {f: (st[f].status, st[f].reason or "") for f in files}
    assert reasons["good.png"][0] == "ok" and reasons["good2.png"][0] == "ok"
    assert reasons["missing.png"][1].startswith("missing")
    assert reasons["truncated.png"][1].startswith("truncated")
    assert reasons["text.png"][1].startswith("unreadable")
    assert reasons["blank.png"][1].startswith("blank")
    assert reasons["wrong.png"][1].startswith("wrong sheet"), reasons["wrong.png"]
    assert "DICT_4X4" in reasons["wrong.png"][1]
    assert reasons["few.png"][1].startswith("too few markers"), reasons["few.png"]
    for f in files:
        if reasons[f][0] != "ok":
            assert reasons[f][0] == "skipped" and "\n" not in reasons[f][1]
    js = meas.images_json()
    assert js[1] == {"file": "missing.png", "status": "skipped",
                     "reason": reasons["missing.png"][1]}
    assert any("stray.png" in r.getMessage() for r in caplog.records)
    # the good photos still measured every mark, with the right ids
    truth = dict(zip([f"c{i}" for i in range(len(targets))], targets))
    assert set(meas.marks) == set(truth)
    err = np.array([meas.marks[k].xy_mm - truth[k] for k in truth])
    assert np.sqrt(np.mean(np.sum(err**2, axis=1))) < 0.015
    assert (tmp_path / "out" / "measurement.json").exists()


def test_out_dir_inside_input_is_refused(tmp_path, world):
    src = tmp_path / "in"
    src.mkdir()
    sm.write_png(src / "good.png", world[3])
    _write(src, world, ["good.png"])
    with pytest.raises(VisionCalError, match="inside the input folder"):
        measure_folder(load_session(src), out_dir=src / "out", jobs=1)


def test_cache_measures_only_new_photos(tmp_path, world, monkeypatch):
    sheet, targets, q, good, good2, *_ = world
    src = tmp_path / "in"
    src.mkdir()
    sm.write_png(src / "a.png", good)
    _write(src, world, ["a.png"])
    calls = []
    real = detect.detect_image

    def counting(path, session, **kw):
        calls.append(os.path.basename(path))
        return real(path, session, **kw)

    monkeypatch.setattr(detect, "detect_image", counting)
    m1 = measure_folder(load_session(src), out_dir=tmp_path / "out", jobs=1)
    assert calls == ["a.png"]
    sm.write_png(src / "b.png", good2)
    _write(src, world, ["a.png", "b.png"])
    calls.clear()
    m2 = measure_folder(load_session(src), out_dir=tmp_path / "out", jobs=1)
    assert calls == ["b.png"]
    assert [im.from_cache for im in m2.images] == [True, False]
    a1, a2 = m1.images[0], m2.images[0]
    np.testing.assert_allclose(a1.dots_xy_mm, a2.dots_xy_mm)
    # changing the photo's bytes invalidates its entry
    img = good.copy()
    img[0, 0] = (1, 2, 3)
    sm.write_png(src / "a.png", img)
    calls.clear()
    measure_folder(load_session(src), out_dir=tmp_path / "out", jobs=1)
    assert calls == ["a.png"]


def test_a_deformed_marker_is_left_out(world):
    sheet, targets, q, good, *_ = world
    ok, buf = cv2.imencode(".png", good)
    s = Session(root=None, sheet=sheet, robot=None, marks=(), images=())
    d = detect_image_bytes(buf.tobytes(), "a.png", s)
    assert d.status == "ok" and len(d.marker_ids) == len(sheet.markers)
    # one corner of marker 3 pulled 2 px off (as when the arm's edge crosses it)
    e = d.edges_px.copy()
    e[3, 1] += 2.0
    bad = replace(d, edges_px=e)
    kept, n = _drop_deformed_markers(bad, None, None)
    assert n == 1 and d.marker_ids[3] not in kept.marker_ids


def test_marker_corners_are_found_once_per_photo_and_lens(tmp_path, world, monkeypatch):
    """Corner fits are kept with the detections: one per lens a photo is seen through, and
    the corners kept for a subset of markers are those a fresh fit of that subset gives."""
    sheet, targets, q, good, *_ = world
    src = tmp_path / "in"
    src.mkdir()
    sm.write_png(src / "a.png", good)
    _write(src, world, ["a.png"])
    calls = []
    real = types.corners_from_edges

    def counting(edges, fallback):
        calls.append(len(edges))
        return real(edges, fallback)

    monkeypatch.setattr(types, "corners_from_edges", counting)
    meas = measure_folder(load_session(src), out_dir=tmp_path / "out", jobs=1)
    lenses = 1 + int(meas.lens is not None and meas.lens.kept)
    assert meas.images[0].status == "ok" and len(calls) == lenses
    ok, buf = cv2.imencode(".png", good)
    d = detect_image_bytes(buf.tobytes(), "a.png", Session(None, sheet, None, (), ()))
    keep = np.arange(len(d.marker_ids)) % 3 != 1
    sub = d.keep_markers(keep)
    np.testing.assert_array_equal(sub.corners_for(), sub._corners_for(None, None))
    assert sub.corners_for() is sub.corners_for()
