"""The printed geometry, read back through a rasteriser that is not the writer (pdfium).

What could fail: a marker drawn at the wrong place, size or orientation, a wrong page
size or scale, the raster (PNG) and the vector (PDF, SVG) disagreeing with sheet.json.
Bound: 0.02 mm per corner (issue 10); the corner finder on a clean raster at 20 px/mm
(0.05 mm per pixel) is good to about 0.1 px = 0.005 mm.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from tests.sheet.raster import (detect_corners_mm, find_bars_mm, px_to_mm, rasterise_mupdf,
                                rasterise_pdf, rasterise_pdftoppm)
from vision_cal.commands.main import main

pytest.importorskip("pypdfium2")

CORNER_TOL_MM = 0.02
PPM = 20.0   # 508 dpi: A4 and the custom page are a whole number of pixels


def _extent(doc):
    x0, y0 = doc["bottom_left_mm"]
    return (x0, y0, x0 + doc["size_mm"][0], y0 + doc["size_mm"][1])


@pytest.fixture(scope="module", params=[
    ["--size", "A4", "--portrait"],
    ["--custom", "300", "250", "--dictionary", "DICT_4X4_50", "--marker-mm", "18"],
], ids=["A4-portrait-5x5", "custom-4x4"])
def printed(request, tmp_path_factory):
    out = tmp_path_factory.mktemp("sheet")
    assert main(["sheet", *request.param, "--png-dpi", str(10 * 25.4), "--out", str(out),
                 "-q"]) == 0
    doc = json.loads((out / "sheet.json").read_text())
    return out, doc


def _corner_errors(found: dict, doc) -> np.ndarray:
    want = {m["id"]: np.array(m["corners_mm"]) for m in doc["markers"]}
    assert set(found) == set(want), "every marker of sheet.json, and no other, is printed"
    return np.array([np.hypot(*(found[i] - want[i]).T) for i in want])


def test_pdf_page_is_the_paper(printed):
    import pypdfium2 as pdfium

    out, doc = printed
    w_pt, h_pt = pdfium.PdfDocument(str(out / "sheet.pdf"))[0].get_size()
    # the page is rounded down to 0.01 pt (3.5 um), never up (see the next-but-one test)
    for got_pt, want_mm in ((w_pt, doc["size_mm"][0]), (h_pt, doc["size_mm"][1])):
        assert -0.0036 < got_pt * 25.4 / 72 - want_mm <= 1e-4   # pdfium: float32


def test_pdf_marker_corners_land_where_sheet_json_says(printed):
    out, doc = printed
    rgb, ppm = rasterise_pdf(out / "sheet.pdf", PPM)
    err = _corner_errors(detect_corners_mm(rgb, doc["aruco_dictionary"], _extent(doc), ppm), doc)
    print(f"PDF via pdfium at {PPM:g} px/mm: corner error max {err.max():.4f} mm, "
          f"RMS {np.sqrt(np.mean(err**2)):.4f} mm over {err.size} corners")
    assert err.max() < CORNER_TOL_MM


def test_pdf_scale_bars_measure_100_mm_where_sheet_json_says(printed):
    out, doc = printed
    rgb, ppm = rasterise_pdf(out / "sheet.pdf", PPM)
    bars = find_bars_mm(rgb, _extent(doc), ppm)
    assert set(bars) == {"x", "y"}
    for axis, k in (("x", 0), ("y", 1)):
        start, end = bars[axis]
        length = end[k] - start[k]
        print(f"{axis} bar: {length:.4f} mm")
        assert length == pytest.approx(100.0, abs=CORNER_TOL_MM)
        want = np.array(doc["printed"]["scale_bars_mm"][axis])
        assert start[k] == pytest.approx(want[0][k], abs=CORNER_TOL_MM)


def _second_rasteriser_agrees(printed, rasterise, name):
    out, doc = printed
    rgb, ppm = rasterise(out / "sheet.pdf", PPM)
    err = _corner_errors(detect_corners_mm(rgb, doc["aruco_dictionary"], _extent(doc), ppm), doc)
    print(f"PDF via {name}: corner error max {err.max():.4f} mm")
    assert err.max() < CORNER_TOL_MM
    bars = find_bars_mm(rgb, _extent(doc), ppm)
    assert bars["x"][1][0] - bars["x"][0][0] == pytest.approx(100.0, abs=CORNER_TOL_MM)
    assert bars["y"][1][1] - bars["y"][0][1] == pytest.approx(100.0, abs=CORNER_TOL_MM)


def test_mupdf_agrees_too(printed):
    """A second rasteriser, installed with the project's tests (MuPDF): corners and bars
    to the same 0.02 mm."""
    _second_rasteriser_agrees(printed, rasterise_mupdf, "MuPDF")


def test_pdftoppm_agrees_too(printed):
    """A third (poppler's pdftoppm, a system tool: skipped saying what to install where it
    is absent, required under CI): corners and bars to the same 0.02 mm."""
    _second_rasteriser_agrees(printed, rasterise_pdftoppm, "pdftoppm")


def test_png_raster_agrees_with_sheet_json(printed):
    from PIL import Image

    out, doc = printed
    im = Image.open(out / "sheet.png")
    assert im.info["dpi"][0] == pytest.approx(254.0, abs=0.01)
    rgb = np.asarray(im.convert("RGB"))
    ppm = 10.0
    err = _corner_errors(detect_corners_mm(rgb, doc["aruco_dictionary"], _extent(doc), ppm), doc)
    assert err.max() < CORNER_TOL_MM
    bars = find_bars_mm(rgb, _extent(doc), ppm)
    assert bars["x"][1][0] - bars["x"][0][0] == pytest.approx(100.0, abs=CORNER_TOL_MM)
    assert bars["y"][1][1] - bars["y"][0][1] == pytest.approx(100.0, abs=CORNER_TOL_MM)


def test_svg_markers_and_size_agree_with_sheet_json(printed):
    out, doc = printed
    root = ET.parse(out / "sheet.svg").getroot()
    assert root.get("width") == f"{doc['size_mm'][0]:g}mm"
    x0, _, _, y1 = _extent(doc)
    ns = "{http://www.w3.org/2000/svg}"
    paths = {int(p.get("id")[6:]): p.get("d") for p in root.iter(f"{ns}path")
             if (p.get("id") or "").startswith("marker")}
    want = {m["id"]: np.array(m["corners_mm"]) for m in doc["markers"]}
    assert set(paths) == set(want)
    for i, d in paths.items():
        # each module "M x y h a v b h -a z": collect the squares' extremes
        xs, ys = [], []
        for sub in d.split("M")[1:]:
            x, rest = sub.split(" ", 1)
            y, rest = rest.split("h", 1)
            a = float(rest.split("v")[0])
            b = float(rest.split("v")[1].split("h")[0])
            xs += [float(x), float(x) + a]
            ys += [float(y), float(y) + b]
        # the border modules reach the marker's outer edges
        got = np.array([[min(xs), min(ys)], [max(xs), max(ys)]])   # svg: y down
        tl = px_to_mm([got[0] - 0.5], (x0, 0, 0, y1), 1.0)[0]
        br = px_to_mm([got[1] - 0.5], (x0, 0, 0, y1), 1.0)[0]
        assert np.allclose(tl, want[i][0], atol=1e-5) and np.allclose(br, want[i][2], atol=1e-5)


@pytest.mark.parametrize("size", ["A4", "A3", "A2", "A1", "A0"])
def test_pdfium_fits_the_page_to_whole_pixels_without_stretching(size, tmp_path):
    """At whole px/mm pdfium's bitmap is exactly the paper (it stretches a page a hair
    larger than N pixels to N + 1: the bug this guards against)."""
    import pypdfium2 as pdfium

    assert main(["sheet", "--size", size, "--out", str(tmp_path), "-q"]) == 0
    doc = json.loads((tmp_path / "sheet.json").read_text())
    page = pdfium.PdfDocument(str(tmp_path / "sheet.pdf"))[0]
    for ppm in (2.0, 6.0):
        bm = page.render(scale=ppm * 25.4 / 72.0)
        assert (bm.width, bm.height) == (round(doc["size_mm"][0] * ppm),
                                         round(doc["size_mm"][1] * ppm))
