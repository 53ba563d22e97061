"""`images` absent from session.json: every photo in the folder, marks found from the photos.

Series (each photo adds a mark in plan order) and finished-sheet photos are told apart by
what is detected; an extra photo (no sheet), a repeated photo and a missing photo of the
series are reported and do not stop the run; order is EXIF capture time, else natural
file name. `vision-cal init` writes the completed list. The input folder is never written.
"""

from __future__ import annotations

import io
import json
import shutil
import stat

import numpy as np
import pytest
from PIL import Image

from tests.measure import synth_measure as sm
from vision_cal.commands.main import main
from vision_cal.dataset.session import load_session
from vision_cal.actions.measure_folder import measure_folder

N = 6


@pytest.fixture(scope="module")
def world():
    sheet = sm.small_sheet()
    targets = sm.free_targets(sheet, N, rng=21, box=(85.0, 62.0))
    q = sm.plan_for(targets)
    views = [sm.view(tilt_deg=8.0 + 2 * k, azimuth_deg=40.0 * k) for k in range(N)]
    series = [sm.photo(sheet, sm.texture(sheet, targets[:k + 1], rng=1), K=K, T=T, rng=10 + k)
              for k, (K, T) in enumerate(views)]
    tex = sm.texture(sheet, targets, rng=1)
    K2, T2 = sm.view(tilt_deg=14.0, azimuth_deg=-70.0)
    finished = [series[-1], sm.photo(sheet, tex, K=K2, T=T2, rng=30)]
    floor = np.random.default_rng(5).integers(40, 200, (750, 1000, 3)).astype(np.uint8)
    # the same series drawn on a sheet that already carries 3 marks of an earlier plan
    pilot = sm.free_targets(sheet, N + 3, rng=21, box=(85.0, 62.0))[N:]
    on_pilot = [sm.photo(sheet, sm.texture(sheet, np.vstack([pilot, targets[:k + 1]]), rng=1),
                         K=K, T=T, rng=40 + k) for k, (K, T) in enumerate(views[:4])]
    return sheet, targets, q, series, finished, floor, on_pilot


IDS = [f"c{i}" for i in range(N)]


def _plan(folder, world):
    sheet, targets, q, *_ = world
    d = sm.session_json(sheet, marks=list(zip(IDS, q)), images=[], robot=sm.NOMINAL)
    del d["images"]
    sm.write_session(folder, d)


def _snapshot(folder):
    return {p.relative_to(folder).as_posix(): (p.stat().st_mtime_ns, p.read_bytes())
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _readonly(folder):
    for p in folder.iterdir():
        p.chmod(stat.S_IRUSR)
    folder.chmod(stat.S_IRUSR | stat.S_IXUSR)


def _err_rms(meas, targets, ids):
    truth = dict(zip(IDS, targets))
    err = np.array([meas.marks[k].xy_mm - truth[k] for k in ids])
    return float(np.sqrt(np.mean(np.sum(err**2, axis=1))))


def test_series_without_images_list(tmp_path, world, capsys):
    """Natural order (s_2 before s_10), a photo of the floor, a repeated file, a photo of
    the series missing: all reported, every photographed mark measured and named, exit 0."""
    sheet, targets, q, series, finished, floor, _ = world
    src = tmp_path / "in"
    src.mkdir()
    names = ["s_1.png", "s_2.png", "s_3.png", "s_9.png", "s_10.png", "s_11.png"]
    for k, name in enumerate(names):
        if k == 3:  # the photo with 4 marks is missing from the folder
            continue
        sm.write_png(src / name, series[k])
    sm.write_png(src / "floor.png", floor)
    shutil.copy(src / "s_2.png", src / "s_2_copy.png")
    again = series[1].copy()  # another photo of the same state: different bytes
    again[:5, :5] = 255 - again[:5, :5]
    sm.write_png(src / "s_2b.png", again)
    (src / "IMG_7.heic").write_bytes(b"\0\0\0\x18ftypheic")  # a phone's format: named
    _plan(src, world)
    before = _snapshot(src)
    _readonly(src)
    try:
        rc = main([str(src), "--out", str(tmp_path / "out"), "-q", "-j", "2"])
    finally:
        src.chmod(stat.S_IRWXU)
    assert rc == 0
    assert _snapshot(src) == before
    err = capsys.readouterr().err.strip().splitlines()
    meas = json.loads((tmp_path / "out" / "measurement.json").read_text())
    files = [im["file"] for im in meas["images"]]
    # natural order, not "s_10" < "s_2"
    order = [f for f in files if f.startswith("s_") and "copy" not in f]
    assert order == ["s_1.png", "s_2.png", "s_2b.png", "s_3.png", "s_10.png", "s_11.png"]
    st = {im["file"]: im for im in meas["images"]}
    assert st["floor.png"]["status"] == "skipped"
    assert st["s_2_copy.png"]["reason"] == "repeated photo: the same file as s_2.png"
    assert meas["inferred"] == "series"
    got = dict(zip(files, meas["image_marks"]))
    assert got["s_1.png"] == ["c0"]
    assert got["s_2b.png"] == got["s_2.png"] == ["c0", "c1"]
    assert got["s_3.png"] == ["c0", "c1", "c2"]
    assert got["s_10.png"] == IDS[:5]
    assert got["s_11.png"] == IDS
    missing = (f"vision-cal: warning: {src}: s_10.png: 2 marks added since s_3.png: a photo "
               "of the series may be missing")
    assert err == [f"vision-cal: warning: {src}/floor.png: skipped: {st['floor.png']['reason']}",
                   f"vision-cal: warning: {src}/s_2_copy.png: skipped: repeated photo: the "
                   "same file as s_2.png",
                   f"vision-cal: warning: {src}: 1 file(s) of a format not read (IMG_7.heic): "
                   "convert them to JPEG or PNG",
                   f"vision-cal: warning: {src}: s_2b.png: a repeated photo (no mark added "
                   "since s_2.png)", missing], err
    truth = dict(zip(IDS, targets))
    e = np.array([np.subtract(meas["marks"][k]["measured_mm"], truth[k]) for k in IDS])
    assert np.sqrt(np.mean(np.sum(e**2, axis=1))) < 0.015


def test_finished_sheet_photos_and_init(tmp_path, world, capsys):
    """Two photos of the finished sheet (and one of the floor): every mark in each."""
    sheet, targets, q, series, finished, floor, _ = world
    src = tmp_path / "photos"
    src.mkdir()
    sm.write_png(src / "a.png", finished[0])
    sm.write_png(src / "b.png", finished[1])
    sm.write_png(src / "robot.png", floor)
    plan = tmp_path / "plan"
    plan.mkdir()
    _plan(plan, world)
    before = _snapshot(src)
    out = tmp_path / "done" / "session.json"
    rc = main(["init", str(src), "--plan", str(plan / "session.json"), "-o", str(out), "-j", "1"])
    assert rc == 0
    assert _snapshot(src) == before
    doc = json.loads(out.read_text())
    assert doc["images"] == [{"file": "a.png", "marks": IDS}, {"file": "b.png", "marks": IDS}]
    assert doc["marks"] == json.loads((plan / "session.json").read_text())["marks"]
    err = capsys.readouterr().err
    assert "robot.png: not used" in err
    assert "2 photo(s) of the sheet (finished)" in err
    # the completed session calibrates like a hand-written one
    shutil.copy(out, src / "session.json")
    s = load_session(src)
    assert s.images_listed and [im.file for im in s.images] == ["a.png", "b.png"]


def test_init_refuses_to_write_into_the_photos(tmp_path, world, capsys):
    src = tmp_path / "photos"
    src.mkdir()
    sm.write_png(src / "a.png", world[4][0])
    _plan(tmp_path, world)
    before = _snapshot(src)
    rc = main(["init", str(src), "--plan", str(tmp_path / "session.json"),
               "-o", str(src / "session.json")])
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "never writes into the photo folder" in err[0]
    assert _snapshot(src) == before


def _jpeg(rgb, when: str | None) -> bytes:
    im = Image.fromarray(rgb)
    ex = im.getexif()
    if when:
        ex.get_ifd(0x8769)[0x9003] = when
    b = io.BytesIO()
    im.save(b, "JPEG", quality=95, exif=ex.tobytes())
    return b.getvalue()


def test_exif_capture_time_orders_the_photos(tmp_path, world):
    """File names in reverse: the capture time decides; without a time on every photo, the
    file name does."""
    sheet, targets, q, series, *_ = world
    src = tmp_path / "in"
    src.mkdir()
    for k in range(3):
        (src / f"z{9 - k}.jpg").write_bytes(_jpeg(series[k], f"2026:11:23 10:00:{10 + k:02d}"))
    _plan(src, world)
    meas = measure_folder(load_session(src), out_dir=tmp_path / "out", jobs=1)
    assert [im.file for im in meas.images] == ["z9.jpg", "z8.jpg", "z7.jpg"]
    assert [len(m) for m in meas.image_marks] == [1, 2, 3]
    assert meas.inferred == "series"
    assert set(meas.marks) == {"c0", "c1", "c2"}
    # one photo without a capture time: all by file name (and said so)
    (src / "z8.jpg").write_bytes(_jpeg(series[1], None))
    meas = measure_folder(load_session(src), out_dir=tmp_path / "out", jobs=1)
    assert [im.file for im in meas.images] == ["z7.jpg", "z8.jpg", "z9.jpg"]
    assert any("1 of 3 photos have no EXIF capture time" in w for w in meas.warnings)
    assert any("1 of 3 photos have no EXIF capture time" in w for w in meas.inferred_notes)


def test_no_photos_at_all_is_one_line(tmp_path, world, capsys):
    src = tmp_path / "in"
    src.mkdir()
    _plan(src, world)
    (src / "IMG_0001.HEIC").write_bytes(b"\0\0\0\x18ftypheic")
    rc = main([str(src), "--out", str(tmp_path / "out")])
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "images: no photos" in err[0], err
    assert "1 file(s) of a format not read (IMG_0001.HEIC): convert them to JPEG" in err[0]
    assert sorted(p.name for p in src.iterdir()) == ["IMG_0001.HEIC", "session.json"]


def _groups(seen):
    from vision_cal.identify.associate import DotGroup

    z = np.zeros((1, 2))
    return [DotGroup(np.repeat(z, len(s), 0), np.zeros((len(s), 2, 2)), tuple(s),
                     tuple([0] * len(s))) for s in seen]


def test_a_dot_seen_once_is_not_a_mark():
    """A reflection in photo 1 only (never seen again) does not shift the series; the dot of
    a mark missed once (photo 3) still counts from where it first appeared."""
    from vision_cal.identify.infer import infer_image_marks

    ids = ["a", "b", "c", "d"]
    files = [f"p{k}" for k in range(4)]
    seen = [{0, 1, 2, 3}, {1, 2}, {2, 3}, {3}, {1}]  # last: the reflection
    got = infer_image_marks(4, [0, 1, 2, 3], _groups(seen), ids, files)
    assert got.mode == "series"
    assert [len(m) for m in got.marks] == [1, 2, 3, 4]
    finished = infer_image_marks(2, [0, 1], _groups([{0, 1}] * 5), ids, files)
    assert finished.mode == "finished" and finished.marks == (tuple(ids), tuple(ids))
    assert any("5 persistent dots" in w for w in finished.warnings)
    # 2 dots on the sheet before the series (an earlier plan): not counted as its marks
    pre = infer_image_marks(4, [0, 1, 2, 3], _groups(seen[:4] + [{0, 1, 2, 3}] * 2), ids,
                            files)
    assert [len(m) for m in pre.marks] == [1, 2, 3, 4]
    assert any("2 dot(s) already on the sheet" in w for w in pre.warnings)


def test_series_on_a_sheet_with_earlier_marks(tmp_path, world):
    sheet, targets, q, series, finished, floor, on_pilot = world
    src = tmp_path / "in"
    src.mkdir()
    for k, img in enumerate(on_pilot):
        sm.write_png(src / f"IMG_{k + 1}.png", img)
    d = sm.session_json(sheet, marks=list(zip(IDS[:4], q[:4])), images=[], robot=sm.NOMINAL)
    del d["images"]
    sm.write_session(src, d)
    meas = measure_folder(load_session(src), out_dir=tmp_path / "out", jobs=1)
    assert meas.inferred == "series"
    assert [len(m) for m in meas.image_marks] == [1, 2, 3, 4]
    assert set(meas.marks) == set(IDS[:4]) and len(meas.unassigned) == 3
    truth = dict(zip(IDS, targets))
    e = np.array([meas.marks[k].xy_mm - truth[k] for k in IDS[:4]])
    assert np.sqrt(np.mean(np.sum(e**2, axis=1))) < 0.015


def test_init_with_no_photo_of_the_sheet_is_one_line(tmp_path, world, capsys):
    src = tmp_path / "photos"
    src.mkdir()
    sm.write_png(src / "floor.png", world[5])
    _plan(tmp_path, world)
    out = tmp_path / "o" / "session.json"
    rc = main(["init", str(src), "--plan", str(tmp_path / "session.json"), "-o", str(out), "-q"])
    assert rc == 2 and not out.exists()
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"vision-cal: error: {src}: no usable photo of the sheet among "
                              "1 image file(s) (first: floor.png: "), err
    assert [ln for ln in err if "error" in ln] == [err[-1]]


def test_progress_counts_and_the_design_preview(tmp_path, world, capsys, monkeypatch):
    """No images list: the progress line counts the photos found (not minus the cache),
    a re-run says all came from the cache (not 0/0), and design's preview.png beside
    session.json is never taken for a photo."""
    import vision_cal.progress as progress

    monkeypatch.setattr(progress, "_tty", lambda: False)
    sheet, targets, q, series, finished, floor, _ = world
    folder = tmp_path / "f"
    folder.mkdir()
    _plan(folder, world)
    sm.write_png(folder / "a.png", finished[0])
    sm.write_png(folder / "b.png", finished[1])
    sm.write_png(folder / "preview.png", floor)
    out = tmp_path / "out"
    m = measure_folder(load_session(folder), out_dir=out, jobs=1, progress=True)
    assert [im.file for im in m.images] == ["a.png", "b.png"]
    err = capsys.readouterr().err
    assert "2/2 photos" in err and "-2" not in err and "from the cache" not in err, err
    measure_folder(load_session(folder), out_dir=out, jobs=1, progress=True)
    err = capsys.readouterr().err
    assert "2/2 photos" in err and "all from the cache" in err and "0/0" not in err, err


def test_a_photo_out_of_order_is_named_and_left_out():
    """Photos of marks 1, 2, 4, 3 (two swapped): the one with 3 marks after the one with 4
    adds nothing and lacks mark 4: named out of order, not 'repeated', and not used (it
    would otherwise claim a mark it does not show). Issue 19."""
    from vision_cal.identify.infer import infer_image_marks

    ids = ["a", "b", "c", "d"]
    files = ["p1", "p2", "p4", "p3"]
    seen = [{0, 1, 2, 3}, {1, 2, 3}, {2, 3}, {2}]  # mark d first seen in p4 (rank 2) only
    got = infer_image_marks(4, [0, 1, 2, 3], _groups(seen), ids, files)
    assert got.mode == "series"
    assert [len(m) for m in got.marks] == [1, 2, 4, 0]
    assert any(w.startswith("p3: out of order") and "left out" in w for w in got.warnings)
    assert not any("repeated" in w for w in got.warnings)


def test_init_on_an_empty_folder_names_the_folder(tmp_path, world, capsys):
    """Issue 19: not PHOTOS/session.json, a file that does not exist."""
    plan = tmp_path / "plan"
    plan.mkdir()
    _plan(plan, world)
    empty = tmp_path / "photos"
    empty.mkdir()
    rc = main(["init", str(empty), "--plan", str(plan / "session.json")])
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"vision-cal: error: {empty}: no photos"), err
    assert "session.json" not in err[0]
    assert list(empty.iterdir()) == []


def test_a_photo_with_one_dot_after_the_finished_sheet_is_not_listed_with_six():
    """Issue 19: a photo showing one of the six dots, taken after one of the finished sheet,
    was listed as showing all six ("a repeated photo"); it is left out, named."""
    from vision_cal.identify.infer import infer_image_marks

    ids = ["a", "b", "c", "d", "e", "f"]
    seen = [{0, 1}] + [{0}] * 5
    got = infer_image_marks(2, [0, 1], _groups(seen), ids, ["all.png", "one.png"])
    assert [len(m) for m in got.marks] == [6, 0]
    assert any(w.startswith("one.png: out of order (it shows 1 marks") for w in got.warnings)
