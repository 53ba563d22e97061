"""Phone photos with bytes after the image (issue 19): a JPEG or PNG is judged by walking
its structure, not by its last bytes, so Samsung's trailer, a motion photo's video or an
appended depth map leave the photo measured exactly as without them; a file that really
ends early, or a PNG chunk failing its CRC, is still refused with one reason."""

from __future__ import annotations

import io
import struct

import numpy as np
import pytest
from PIL import Image

from tests.measure import synth_measure as sm
from tests.measure.test_photo_files import _run, _session, _status, world  # noqa: F401
from vision_cal.dataset import photos


def _jpeg(rgb, *, progressive=False) -> bytes:
    b = io.BytesIO()
    Image.fromarray(rgb).save(b, "JPEG", quality=95, progressive=progressive)
    return b.getvalue()


def _png(rgb) -> bytes:
    b = io.BytesIO()
    Image.fromarray(rgb).save(b, "PNG")
    return b.getvalue()


def samsung_trailer() -> bytes:
    """Samsung's SEF trailer as phones write it after the JPEG's end marker: data blocks
    (here ``Image_UTC_Data`` with a millisecond time stamp), the ``SEFH`` directory, the
    directory's length and ``SEFT``."""
    name = b"Image_UTC_Data"
    block = struct.pack("<HHI", 0, 0x0A01, len(name)) + name + b"1700000000123"
    sefh = b"SEFH" + struct.pack("<II", 107, 1) + struct.pack("<HHII", 0, 0x0A01,
                                                              len(block) + 8, len(block))
    return block + sefh + struct.pack("<I", len(sefh)) + b"SEFT"


def motion_photo_trailer() -> bytes:
    """A motion photo: an MP4 (``ftyp``, ``mdat`` holding bytes that include ``FFD8`` and
    ``FFD9``, as video data does) appended after the still's end marker."""
    ftyp = struct.pack(">I", 24) + b"ftypmp42" + struct.pack(">I", 0) + b"isommp42"
    payload = bytes(np.random.default_rng(4).integers(0, 256, 3000, dtype=np.uint8)) \
        + b"\xff\xd8\xff\xd9" + b"\x00" * 40
    return ftyp + struct.pack(">I", 8 + len(payload)) + b"mdat" + payload


def depth_map_trailer(rgb) -> bytes:
    """A second JPEG (a depth map, as MPF multi-picture files carry) after the first."""
    return _jpeg(np.ascontiguousarray(rgb[::4, ::4]))


@pytest.mark.parametrize("kind", ["depth", "progressive-samsung"])
def test_trailer_layouts_are_complete_and_decode_the_same(world, kind):  # noqa: F811
    img = world[3]
    base = _jpeg(img, progressive=kind.startswith("progressive"))
    trailer = depth_map_trailer(img) if kind == "depth" else samsung_trailer()
    photos.check_complete(base + trailer)
    assert photos.decode_photo(base + trailer).tobytes() == photos.decode_photo(base).tobytes()


def test_photos_with_trailers_measure_like_without(tmp_path, world, capsys):  # noqa: F811
    """One folder: a JPEG and a PNG, and the same bytes with Samsung's trailer and a motion
    photo's video appended; every photo is used and measures exactly like its plain twin."""
    src = tmp_path / "in"
    src.mkdir()
    jpg, png = _jpeg(world[3]), _png(world[3])
    files = {"plain.jpg": jpg, "samsung.jpg": jpg + samsung_trailer(),
             "motion.jpg": jpg + motion_photo_trailer(), "plain.png": png,
             "trailer.png": png + samsung_trailer()}
    for name, data in files.items():
        (src / name).write_bytes(data)
    assert photos.decode_photo(files["motion.jpg"]).tobytes() == photos.decode_photo(jpg).tobytes()
    _session(src, world, list(files))
    rc, err, doc = _run(src, tmp_path / "out", capsys)
    assert rc == 0 and err == [], err
    assert set(_status(doc).values()) == {("ok", "")}
    im = {i["file"]: dict(i, file=None) for i in doc["images"]}
    # the same pixels measure the same: each record identical to its plain twin's
    assert im["samsung.jpg"] == im["plain.jpg"] and im["motion.jpg"] == im["plain.jpg"]
    assert im["trailer.png"] == im["plain.png"]


@pytest.mark.parametrize("cut,reason", [
    (lambda b: b[: len(b) * 2 // 3], "truncated"),          # ends in the scan
    (lambda b: b[:300], "truncated"),                       # ends in a header segment
    (lambda b: b[: len(b) // 2] + samsung_trailer(), "truncated"),  # a trailer can't hide it
])
def test_a_jpeg_that_ends_early_is_still_refused(world, cut, reason):  # noqa: F811
    data = cut(_jpeg(world[3]))
    with pytest.raises(photos.PhotoRefused, match=reason):
        photos.check_complete(data)


def test_a_png_that_ends_early_or_fails_its_crc_is_refused(world):  # noqa: F811
    data = _png(world[3])
    with pytest.raises(photos.PhotoRefused, match="truncated"):
        photos.check_complete(data[: len(data) // 2] + samsung_trailer())
    bad = bytearray(data)
    bad[len(bad) // 2] ^= 0xFF  # one byte of the pixel data flipped
    with pytest.raises(photos.PhotoRefused, match="IDAT chunk fails its CRC"):
        photos.check_complete(bytes(bad))
    photos.check_complete(data + b"\x00" * 100)


def test_a_crc_error_is_one_reason(tmp_path, world, capsys):  # noqa: F811
    """Refused from its structure before libpng decodes it (and prints its own line)."""
    src = tmp_path / "in"
    src.mkdir()
    sm.write_png(src / "a.png", world[3])
    sm.write_png(src / "b.png", world[4])
    bad = bytearray((src / "b.png").read_bytes())
    bad[len(bad) // 2] ^= 0xFF
    (src / "b.png").write_bytes(bytes(bad))
    _session(src, world, ["a.png", "b.png"])
    rc, err, doc = _run(src, tmp_path / "out", capsys)
    assert rc == 0 and _status(doc)["b.png"][0] == "skipped"
    assert "CRC" in _status(doc)["b.png"][1]
    assert len(err) == 1 and "b.png" in err[0] and "CRC" in err[0]


def test_a_heic_listed_in_session_json_says_convert_it(tmp_path, world, capsys):  # noqa: F811
    """Issue 19: the same advice as for a folder without a list, not 'no header'."""
    src = tmp_path / "in"
    src.mkdir()
    sm.write_png(src / "a.png", world[3])
    (src / "IMG_0001.HEIC").write_bytes(b"\0\0\0\x18ftypheic" + b"\0" * 64)
    _session(src, world, ["a.png", "IMG_0001.HEIC"])
    rc, err, doc = _run(src, tmp_path / "out", capsys)
    assert rc == 0
    assert _status(doc)["IMG_0001.HEIC"] == (
        "skipped", "a HEIC file, a format not read: convert it to JPEG or PNG")
    assert len(err) == 1 and "IMG_0001.HEIC" in err[0]
