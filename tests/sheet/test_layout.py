"""Layout geometry for every page, sheet.json through the session reader, bad arguments."""

from __future__ import annotations

import json

import numpy as np
import pytest

from vision_cal.commands.main import main
from vision_cal.dataset.session import load_session
from vision_cal.sheet import ISO_SIZES_MM, make_layout
from vision_cal.sheet.layout import Rect

PAGES = [(s, land) for s in ISO_SIZES_MM for land in (True, False)]


def _session(tmp_path, sheet: dict):
    doc = {"format": "vision-cal/1", "sheet": sheet,
           "robot": {"L1_mm": 350.0, "L2_mm": 260.0, "joint_zero_deg": [0.0, 0.0],
                     "base_mm": [-250.0, 0.0]},
           "marks": [{"id": "c00", "joints_deg": [0.0, 0.0], "measured_mm": [1.0, 2.0]}]}
    (tmp_path / "session.json").write_text(json.dumps(doc))
    return load_session(tmp_path)


def _inside(box, outer, tol=1e-9):
    return (box[0] >= outer[0] - tol and box[1] >= outer[1] - tol and box[2] <= outer[2] + tol
            and box[3] <= outer[3] + tol)


def _overlap(a, b):
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


@pytest.mark.parametrize("size,landscape", PAGES)
def test_every_iso_page_gives_a_valid_layout(size, landscape, tmp_path):
    lay = make_layout(size=size, landscape=landscape)
    W, H = lay.size_mm
    assert (W > H) == landscape and sorted((W, H)) == sorted(ISO_SIZES_MM[size])
    doc = lay.to_sheet_json()
    ses = _session(tmp_path, doc)                      # the project's own reader accepts it
    assert ses.sheet.size_mm == (W, H) and len(ses.sheet.markers) == len(doc["markers"]) >= 8
    paper = lay.extent_mm
    quiet = lay.quiet_boxes_mm()
    q = doc["printed"]["quiet_zone_mm"]
    for m, box in zip(doc["markers"], quiet):
        c = np.array(m["corners_mm"])
        s = c[1, 0] - c[0, 0]
        # contract order TL, TR, BR, BL with y up, a square of the printed size
        assert np.allclose(c, [[c[3, 0], c[3, 1] + s], [c[3, 0] + s, c[3, 1] + s],
                               [c[3, 0] + s, c[3, 1]], c[3]])
        assert s == pytest.approx(doc["printed"]["module_mm"] * 7)
        assert _inside(box, paper) and box[0] >= paper[0] + 5 and box[1] >= paper[1] + 5
        assert np.allclose(box, [c[3, 0] - q, c[3, 1] - q, c[1, 0] + q, c[1, 1] + q])
    for i in range(len(quiet)):                       # quiet zones never overlap
        assert not any(_overlap(quiet[i], quiet[j]) for j in range(i + 1, len(quiet)))
    grid = doc["grid"]
    g = grid["extent_mm"]
    assert all(float(v).is_integer() for v in g), "grid lines at whole mm from the origin"
    assert grid["origin_mm"] == [0.0, 0.0] and grid["pitch_mm"] == 1.0
    # grid clear of quiet zones; every printed line at a whole mm
    lines = [p for p in lay.primitives if isinstance(p, Rect) and p.rgb in
             ((196, 228, 222), (150, 205, 196))]
    for ln in lines:
        box = (ln.x0, ln.y0, ln.x1, ln.y1)
        assert not any(_overlap(box, qb) for qb in quiet)
        centre = (ln.x0 + ln.x1) / 2 if ln.x1 - ln.x0 < 1 else (ln.y0 + ln.y1) / 2
        assert centre == pytest.approx(round(centre), abs=1e-9)
    d = doc["printed"]["drawable_mm"]
    assert _inside(d, g) and d[2] - d[0] > 100 and d[3] - d[1] > 100
    assert not any(_overlap(d, qb) for qb in quiet)
    for axis, k in (("x", 0), ("y", 1)):
        (a, b) = np.array(doc["printed"]["scale_bars_mm"][axis])
        assert b[k] - a[k] == pytest.approx(100.0) and _inside((*a, *b), g)
    assert doc["printed"]["page"] == {"name": size, "orientation":
                                      "landscape" if landscape else "portrait",
                                      "size_mm": [W, H]}


@pytest.mark.parametrize("dictionary,bits", [("DICT_4X4_50", 4), ("DICT_6X6_250", 6),
                                             ("DICT_7X7_100", 7), ("DICT_ARUCO_ORIGINAL", 5),
                                             ("DICT_APRILTAG_36h11", 6)])
def test_any_opencv_dictionary_prints_its_own_bits(dictionary, bits):
    import cv2

    lay = make_layout(size="A4", dictionary=dictionary)
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    for m in lay.markers[:3]:
        assert m.bits.shape == (bits + 2, bits + 2)
        assert m.bits[0].all() and m.bits[-1].all() and m.bits[:, 0].all() and m.bits[:, -1].all()
        white = (m.bits[1:-1, 1:-1] == 0).astype(np.uint8)     # OpenCV's bit 1 is white
        ok, idx, rotation = d.identify(white, 0.0)
        assert ok and idx == m.id and rotation == 0


def test_overrides_are_honoured_and_the_id_follows_the_geometry():
    a = make_layout(size="A3", marker_mm=28.0, pitch_mm=60.0)
    assert a.marker_mm == pytest.approx(28.0)
    c = np.array([m.corners_mm()[3] for m in a.markers])
    steps = np.abs(np.diff(c, axis=0)).max(axis=1)
    assert steps.max() <= 60.0 + 1e-9
    assert a.sheet_id != make_layout(size="A3").sheet_id
    assert a.sheet_id == make_layout(size="A3", marker_mm=28.0, pitch_mm=60.0).sheet_id


def test_custom_size_and_measured_bars(tmp_path):
    assert main(["sheet", "--custom", "500", "350", "--portrait", "--measured-bar-mm", "99.8",
                 "100.1", "--out", str(tmp_path), "-q"]) == 0
    doc = json.loads((tmp_path / "sheet.json").read_text())
    assert doc["size_mm"] == [350.0, 500.0]
    assert doc["printed"]["measured_bar_mm"] == [99.8, 100.1]
    assert sorted(p.name for p in tmp_path.iterdir()
                  if not p.name.startswith(".")) == ["sheet.json", "sheet.pdf", "sheet.svg"]


@pytest.mark.parametrize("argv,field", [
    (["--size", "B5"], "--size"),
    (["--dictionary", "DICT_9X9_1"], "--dictionary"),
    (["--custom", "150", "120"], "--custom"),
    (["--pitch-mm", "5"], "--pitch-mm"),
    (["--marker-mm", "-3"], "--marker-mm"),
    (["--marker-mm", "90", "--size", "A4"], "--marker-mm"),
    (["--measured-bar-mm", "0", "100"], "--measured-bar-mm"),
    (["--png-dpi", "-300"], "--png-dpi"),
    (["--size", "A4", "--custom", "300", "300"], "--custom"),
    (["--size", "A0", "--dictionary", "DICT_4X4_50", "--marker-mm", "10", "--pitch-mm", "17"],
     "--dictionary"),
])
def test_bad_arguments_one_line_exit_2_nothing_written(argv, field, tmp_path, capsys):
    out = tmp_path / "o"
    try:
        rc = main(["sheet", *argv, "--out", str(out)])
    except SystemExit as e:   # out of the option's range: refused at parsing
        rc = e.code
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and field in err, err
    assert not out.exists() or not any(out.iterdir())


def test_non_numeric_argument_exits_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["sheet", "--marker-mm", "big", "--out", str(tmp_path)])
    assert e.value.code == 2
    assert "--marker-mm" in capsys.readouterr().err.strip().splitlines()[-1]
