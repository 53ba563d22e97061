"""Photo files at the boundary (issue 11): names, subfolders, symlinks, FIFOs, NUL bytes,
EXIF orientation with and without a declared camera, decompression bombs.

Each case runs the CLI and asserts the exit code, the one line, and that nothing was
written into the input folder.
"""

from __future__ import annotations

import io
import json
import os
import signal
import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from tests.measure import synth_measure as sm
from vision_cal.commands.main import main
from vision_cal.dataset import photos
from vision_cal.measure import detect

N = 6
IDS = [f"c{i}" for i in range(N)]


@pytest.fixture(scope="module")
def world():
    sheet = sm.small_sheet()
    targets = sm.free_targets(sheet, N, rng=21, box=(85.0, 62.0))
    q = sm.plan_for(targets)
    tex = sm.texture(sheet, targets, rng=1)
    K, T = sm.view(tilt_deg=10.0, azimuth_deg=60.0)
    good = sm.photo(sheet, tex, K=K, T=T, rng=2)
    K2, T2 = sm.view(tilt_deg=14.0, azimuth_deg=-70.0)
    good2 = sm.photo(sheet, tex, K=K2, T=T2, rng=3)
    return sheet, targets, q, good, good2, K


def _session(folder, world, files, *, camera=False):
    sheet, targets, q, *_ , K = world
    d = sm.session_json(sheet, marks=list(zip(IDS, q)), images=[(f, IDS) for f in files],
                        robot=sm.NOMINAL, camera=(K, [0.0] * 5) if camera else None)
    sm.write_session(folder, d)
    return d


def _snapshot(folder):
    out = {}
    for p in sorted(folder.rglob("*")):
        if p.is_symlink() or not p.is_file():
            out[p.relative_to(folder).as_posix()] = os.readlink(p) if p.is_symlink() else "dir"
        else:
            out[p.relative_to(folder).as_posix()] = (p.stat().st_mtime_ns, p.read_bytes())
    return out


def _run(src, out, capsys, *extra):
    """(exit code, stderr lines, calibration.json or None)."""
    before = _snapshot(src)

    def hang(*_):
        raise TimeoutError("the run hung")

    old = signal.signal(signal.SIGALRM, hang)
    # a guard against a FIFO that blocks forever, not a speed limit: a run takes seconds on
    # an idle machine and may take minutes on a loaded one (120 s failed under load)
    signal.alarm(1800)
    try:
        rc = main([str(src), "--out", str(out), "-q", "-j", "1", *extra])
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    assert _snapshot(src) == before, "the input folder was written"
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    cal = out / "calibration.json"
    return rc, err, json.loads(cal.read_text()) if cal.exists() else None


def _status(doc):
    return {im["file"]: (im["status"], im.get("reason", "")) for im in doc["images"]}


def _mark_err(doc, world):
    truth = dict(zip(IDS, world[1]))
    e = np.array([np.subtract(doc["marks"][k]["measured_mm"], truth[k]) for k in IDS])
    return float(np.sqrt(np.mean(np.sum(e**2, axis=1))))


# --------------------------------------------------------------------------- names

def test_same_photo_listed_twice_through_dot_slash(tmp_path, world, capsys):
    src = tmp_path / "in"
    src.mkdir()
    sm.write_png(src / "a.png", world[3])
    _session(src, world, ["a.png", "./a.png"])
    rc, err, doc = _run(src, tmp_path / "out", capsys)
    assert rc == 2 and doc is None
    assert err == [f"vision-cal: error: {src / 'session.json'}: images[1].file: duplicate image "
                   "file './a.png' (images[0].file names it as 'a.png')"]


def test_nul_byte_in_a_file_name(tmp_path, world, capsys):
    src = tmp_path / "in"
    src.mkdir()
    sm.write_png(src / "a.png", world[3])
    _session(src, world, ["a\x00.png"])
    rc, err, doc = _run(src, tmp_path / "out", capsys)
    assert rc == 2 and doc is None and len(err) == 1
    assert "images[0].file: expected a file name, got one with a NUL byte" in err[0]


def test_photos_in_subfolders_keep_their_path(tmp_path, world, capsys):
    """photos/x.png stays photos/x.png: two subfolders with the same name do not collide,
    and the report shows both photos."""
    src = tmp_path / "in"
    (src / "left").mkdir(parents=True)
    (src / "right").mkdir()
    sm.write_png(src / "left" / "x.png", world[3])
    sm.write_png(src / "right" / "x.png", world[4])
    _session(src, world, ["left/x.png", "./right/x.png"])
    rc, err, doc = _run(src, tmp_path / "out", capsys, "--report")
    assert rc == 0 and err == []
    assert _status(doc) == {"left/x.png": ("ok", ""), "right/x.png": ("ok", "")}
    rep = json.loads((tmp_path / "out" / "report.json").read_text())
    assert [p["file"] for p in rep["photos"]] == ["left/x.png", "right/x.png"]
    html = (tmp_path / "out" / "report.html").read_text()
    assert html.count("<figure>") == 2
    assert _mark_err(doc, world) < 0.015


def test_symlink_leading_outside_is_refused(tmp_path, world, capsys):
    src = tmp_path / "in"
    src.mkdir()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    sm.write_png(src / "a.png", world[3])
    sm.write_png(elsewhere / "b.png", world[4])
    (src / "b.png").symlink_to(elsewhere / "b.png")
    (src / "c.png").symlink_to("a.png")  # inside: fine (same bytes: a repeated photo)
    _session(src, world, ["a.png", "b.png", "c.png"])
    rc, err, doc = _run(src, tmp_path / "out", capsys)
    assert rc == 0
    st = _status(doc)
    assert st["a.png"][0] == "ok"
    assert st["b.png"] == ("skipped", "refused: it resolves outside the dataset folder "
                                      "(a symlink?)")
    assert st["c.png"] == ("skipped", "repeated photo: the same file as a.png")
    assert err == [f"vision-cal: warning: {src}/b.png: skipped: {st['b.png'][1]}",
                   f"vision-cal: warning: {src}/c.png: skipped: {st['c.png'][1]}"]


@pytest.mark.parametrize("listed", [True, False])
def test_a_fifo_in_place_of_a_photo_does_not_hang(tmp_path, world, capsys, listed):
    src = tmp_path / "in"
    src.mkdir()
    sm.write_png(src / "a.png", world[3])
    os.mkfifo(src / "b.png")
    d = _session(src, world, ["a.png", "b.png"])
    if not listed:
        del d["images"]
        sm.write_session(src, d)
    rc, err, doc = _run(src, tmp_path / "out", capsys)
    assert rc == 0
    assert _status(doc)["b.png"] == ("skipped", "refused: not a regular file (a FIFO)")
    assert err == [f"vision-cal: warning: {src}/b.png: skipped: refused: not a regular file "
                   "(a FIFO)"]


# --------------------------------------------------------------------------- orientation

def _jpeg(rgb, orientation: int) -> bytes:
    im = Image.fromarray(rgb)
    ex = im.getexif()
    ex[0x0112] = orientation
    b = io.BytesIO()
    im.save(b, "JPEG", quality=97, exif=ex.tobytes())
    return b.getvalue()


@pytest.mark.parametrize("camera", [True, False])
def test_exif_rotated_photo_is_measured_in_the_sensor_frame(tmp_path, world, capsys, camera):
    """A phone held upright: the sensor's 1000x750 pixels stored as they are, tagged
    Orientation 6 (OpenCV 5 would turn them to 750x1000 on reading). Measured the same with
    and without a declared camera: not skipped as "wrong size"."""
    src = tmp_path / "in"
    src.mkdir()
    (src / "up.jpg").write_bytes(_jpeg(world[3], 6))
    _session(src, world, ["up.jpg"], camera=camera)
    rc, err, doc = _run(src, tmp_path / "out", capsys)
    assert rc == 0 and err == []
    assert _status(doc) == {"up.jpg": ("ok", "")}
    meas = json.loads((tmp_path / "out" / "measurement.json").read_text())
    assert meas["images"][0]["status"] == "ok"
    assert _mark_err(doc, world) < 0.03


def test_declared_camera_in_the_displayed_frame(tmp_path, world, capsys):
    """The pixels stored turned by 90 deg and tagged to be shown upright; camera.size_px
    describes the shown 1000x750 frame: the photo is decoded turned, to match it."""
    src = tmp_path / "in"
    src.mkdir()
    stored = np.ascontiguousarray(np.rot90(world[3], 1))  # 750 wide, 1000 high
    data = _jpeg(stored, 6)  # 6: turn 90 deg clockwise to display
    shown = photos.decode_photo(data, turned=True)[:, :, ::-1]
    assert shown.shape == world[3].shape
    assert np.mean(np.abs(shown.astype(int) - world[3])) < 3.0
    (src / "turned.jpg").write_bytes(data)
    _session(src, world, ["turned.jpg"], camera=True)
    rc, err, doc = _run(src, tmp_path / "out", capsys)
    assert rc == 0 and err == [] and _status(doc) == {"turned.jpg": ("ok", "")}
    assert _mark_err(doc, world) < 0.03


# --------------------------------------------------------------------------- bombs

def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return (struct.pack(">I", len(data)) + kind + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))


def bomb_png(w: int, h: int, *, full: bool = True) -> bytes:
    """A grey PNG of w x h zero pixels, compressed ~1000:1 (``full``), or a header claiming
    that size over a few bytes of data."""
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0)
    z = zlib.compressobj(9)
    row = b"\x00" * (w + 1)
    if full:
        parts = []
        block = row * max(1, (1 << 24) // len(row))
        n_rows = len(block) // len(row)
        left = h
        while left > 0:
            k = min(left, n_rows)
            parts.append(z.compress(block[:k * len(row)]))
            left -= k
        idat = b"".join(parts) + z.flush()
    else:
        idat = z.compress(row * 4) + z.flush()
    return (b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", ihdr) + _png_chunk(b"IDAT", idat)
            + _png_chunk(b"IEND", b""))


@pytest.fixture(scope="module")
def bombs():
    return {"bomb30k.png": bomb_png(30000, 30000),          # 900 MP in ~1 MB
            "bomb12k.png": bomb_png(12000, 12000),          # 144 MP: under Pillow's error
            "claims100k.png": bomb_png(100000, 100000, full=False)}


@pytest.mark.parametrize("camera", [False, True])
def test_decompression_bombs_are_refused_before_decoding(tmp_path, world, bombs, capsys,
                                                         monkeypatch, camera):
    src = tmp_path / "in"
    src.mkdir()
    sm.write_png(src / "a.png", world[3])
    for name, data in bombs.items():
        (src / name).write_bytes(data)
    assert len(bombs["bomb30k.png"]) < 1.5e6
    files = ["a.png", *bombs]
    _session(src, world, files, camera=camera)
    sent = []
    real = detect.detect_image

    def spy(path, session, **kw):
        sent.append(kw.get("name"))
        return real(path, session, **kw)

    monkeypatch.setattr(detect, "detect_image", spy)
    limit = Image.MAX_IMAGE_PIXELS
    rc, err, doc = _run(src, tmp_path / "out", capsys)
    assert Image.MAX_IMAGE_PIXELS == limit  # Pillow's global guard left as it was
    assert rc == 0 and sent == ["a.png"]  # nothing but the real photo reached a worker
    st = _status(doc)
    assert st["a.png"][0] == "ok"
    if camera:
        assert st["bomb12k.png"] == ("skipped", "wrong size: 12000x12000 px (144.0 MP, not "
                                                "decoded), camera.size_px says 1000x750")
    else:
        assert st["bomb12k.png"] == ("skipped", "refused before decoding: 12000x12000 px "
                                                "(144 MP) is above the 100 MP limit (a "
                                                "decompression bomb?)")
    for name in ("bomb30k.png", "claims100k.png"):
        assert st[name][0] == "skipped" and "MP" in st[name][1], st[name]
        assert st[name][1].startswith(("refused before decoding", "wrong size"))
    assert len(err) == 3 and all(": skipped: " in ln for ln in err)
    assert _mark_err(doc, world) < 0.015


def test_bombs_in_a_folder_without_images_list(tmp_path, world, bombs, capsys):
    src = tmp_path / "in"
    src.mkdir()
    sm.write_png(src / "a.png", world[3])
    (src / "claims100k.png").write_bytes(bombs["claims100k.png"])
    d = _session(src, world, [])
    del d["images"]
    sm.write_session(src, d)
    rc, err, doc = _run(src, tmp_path / "out", capsys, "-j", "2")
    assert rc == 0
    st = _status(doc)
    assert st["a.png"][0] == "ok" and st["claims100k.png"][1].startswith("refused before")


def test_one_owner_for_names():
    assert photos.normalise_name("./a/./b.png") == "a/b.png"
    for bad in ("/etc/passwd", "../x.png", "a/../../x.png", "a\\b.png", "a\x00b", ".", ""):
        with pytest.raises(ValueError):
            photos.normalise_name(bad)
    assert photos.list_photos.__doc__ and sorted(["i10", "i2", "i1"], key=photos.natural_key) \
        == ["i1", "i2", "i10"]


def test_the_header_is_read_without_decoding(bombs, monkeypatch):
    from PIL import ImageFile

    loads = []
    monkeypatch.setattr(ImageFile.ImageFile, "load", lambda *a, **k: loads.append(a))
    h = photos.read_header(bombs["bomb12k.png"])
    assert loads == [], "pixels decoded while reading the header"
    assert h.stored_px == (12000, 12000) and h.orientation == 1
    with pytest.raises(photos.PhotoRefused, match="refused before decoding"):
        photos.check_header(h)


def test_workers_do_not_multiply_the_largest_photo():
    from vision_cal.measure.detect import MAX_PIXELS_IN_FLIGHT, jobs_for

    assert MAX_PIXELS_IN_FLIGHT <= 2 * photos.MAX_PIXELS
    assert jobs_for(8, [12_000_000] * 5) == 8          # phone photos: every core
    assert jobs_for(8, [12_000_000, 90_000_000]) == 2  # two 90 MP photos at most
    assert jobs_for(8, [100_000_000]) == 2
    assert jobs_for(1, [100_000_000]) == 1 and jobs_for(4, []) == 4
