"""Pen marks on printed ink (issue 18 section 1): measured against the sheet's own print or
flagged unreliable, never silently biased.

Photos of the sheet's own raster (``vision-cal sheet --png-dpi 254``, A4) with marks on every
kind of printed content (axes, the origin, the arrow, the axis letter, "origin (0, 0)", grid
numbers, the scale bars, the instruction and title text) and on plain paper; the physical
bound is 0.03 mm (what the issue asks; the plain-paper marks measure 0.01-0.02 mm).
"""

import json

import cv2
import numpy as np
import pytest

from tests.measure.synth_measure import photo, view, one_mark_session
from vision_cal.measure.detect import detect_image_bytes
from vision_cal.measure.finish import finish_image
from vision_cal.measure.printed import printed_reference
from vision_cal.world.printed import load_printed_sheet, printed_texture
from vision_cal.sheet import make_layout, write_sheet

#: sheet mm on the A4 layout: where each kind of printed content is
ON_PRINT = {"origin": (0.0, 0.0), "x axis": (6.0, 0.0), "y axis": (0.0, 7.0),
            "arrow": (13.3, 0.2), "axis letter": (16.8, 0.3), "origin text": (-8.0, -2.6),
            "x number": (30.0, 74.1), "y number": (117.8, 20.0), "x bar": (-60.0, -65.75),
            "y bar": (-113.75, 0.0), "title": (-80.0, -72.2), "instruction": (-60.0, -69.0)}
PLAIN = {"p1": (20.5, 30.5), "p2": (-40.5, 20.5), "p3": (50.5, -30.5), "p4": (-70.5, 40.5)}
SIZE = (2000, 1500)


@pytest.fixture(scope="module")
def a4(tmp_path_factory):
    d = tmp_path_factory.mktemp("a4")
    write_sheet(make_layout(size="A4"), d, png_dpi=254)
    return d


def _measure(a4, folder, seed, *, describe=True):
    """Per mark name: (error mm, unreliable reason, printed under) on one photo."""
    pr = load_printed_sheet(a4 / "sheet.json")
    rng = np.random.default_rng(seed)
    names = [*ON_PRINT, *PLAIN]
    xy = np.array([{**ON_PRINT, **PLAIN}[k] for k in names]) + rng.normal(0, 0.15, (len(names), 2))
    tex = printed_texture(pr, marks_xy_mm=xy, mark_diameters_mm=1.2, rng=seed)
    K, T = view(tilt_deg=15, azimuth_deg=40 + 30 * seed, f_px=1400, dist_mm=210, size=SIZE)
    img = photo(pr.sheet, tex, K=K, T=T, size=SIZE, ppm=pr.px_per_mm, noise=2.0, blur_mm=0.12,
                rng=seed)
    sheet = json.loads((a4 / "sheet.json").read_text())
    if not describe:
        sheet.pop("printed")
    session = one_mark_session(folder, sheet, "a.png")
    ok, buf = cv2.imencode(".png", cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    r = finish_image(detect_image_bytes(buf.tobytes(), "a.png", session), session)
    assert r.status == "ok"
    out = {}
    for k, p in zip(names, xy):
        d = np.hypot(*(r.dots_xy_mm - p).T)
        j = int(np.argmin(d))
        assert d[j] < 1.0, f"{k}: not found"
        out[k] = (float(d[j]), r.dots_unreliable[j], r.dots_printed_under[j])
    return out


def test_the_sheet_json_of_our_generator_gives_its_print(a4):
    ref = printed_reference(load_session_sheet(a4))
    assert ref is not None
    kinds = {it.kind for it in ref.content_near((0.0, 0.0), 20.0)}
    assert {"axis", "arrow", "text"} <= kinds
    assert [it.label for it in ref.content_near((-60.0, -65.75), 0.5)] == ["x scale bar"]
    assert ref.content_near(PLAIN["p1"], 1.0) == []
    # another generator's sheet (same markers) is not described: no reference
    doc = json.loads((a4 / "sheet.json").read_text())
    doc["printed"]["generator"] = "someone else's"
    assert printed_reference(_sheet_of(doc)) is None
    doc = json.loads((a4 / "sheet.json").read_text())
    doc["printed"]["sheet_id"] = "00000000"       # a layout that is not this one
    assert printed_reference(_sheet_of(doc)) is None


def load_session_sheet(a4):
    return _sheet_of(json.loads((a4 / "sheet.json").read_text()))


def _sheet_of(doc):
    from vision_cal.dataset.fields import FieldReader
    from vision_cal.dataset.session import read_sheet_block

    return read_sheet_block(FieldReader("sheet.json"), doc, "")


@pytest.mark.parametrize("seed", [5, 8])
def test_marks_on_print_are_measured_against_the_print(a4, tmp_path, seed):
    res = _measure(a4, tmp_path / "d", seed)
    for k, (err, why, under) in res.items():
        print(f"{k:12s} {err:.4f} {under!r} {why!r}")
    for k in ON_PRINT:
        err, why, under = res[k]
        assert under, k                            # the print under it is known
        assert err < 0.03 or why, (k, err)         # within 0.03 mm or flagged
    for k in PLAIN:                                # clean paper: nothing claimed
        err, why, under = res[k]
        assert err < 0.03 and not why and not under, (k, err, why, under)
    # where the photo shows the print as the reference draws it, the ground around a mark
    # on text pins the print's edges: good marks on text are kept (issue 28 s4's leftover:
    # every one flagged for a 50 um edge move the photo excludes; here 3 of 6 kept)
    text = ("axis letter", "origin text", "x number", "y number", "title", "instruction")
    kept = [k for k in text if res[k][0] < 0.015 and not res[k][1]]
    assert len(kept) >= 2, kept


@pytest.mark.parametrize("seed", [7, 200])
def test_a_sheet_nobody_describes_flags_what_it_cannot_separate(a4, tmp_path, seed):
    """Without the print's description only the photo tells: every mark on print within
    0.03 mm or flagged (seed 200: the axis letter and a grid number leave the paper-and-grid
    model under its residual limit but pull the centre 0.04-0.06 mm; the ink beside the
    window says so), the scale bars measured against the markers (the printed grid around
    them is interrupted by the bar), nothing claimed on plain paper."""
    res = _measure(a4, tmp_path / "d", seed, describe=False)
    for k, (err, why, under) in res.items():
        print(f"{k:12s} {err:.4f} {why!r}")
    for k in ON_PRINT:
        err, why, _ = res[k]
        assert err < 0.03 or why, (k, err)
    for k in ("x bar", "y bar"):
        assert res[k][0] < 0.03, k
    for k in PLAIN:
        assert res[k][0] < 0.03 and not res[k][1], k


@pytest.fixture(scope="module")
def a4_pdf(tmp_path_factory, a4):
    """The same sheet photographed as pdfium draws its PDF (not the sheet's own raster
    writer, which the measurement's reference uses): other glyphs, other edges."""
    pytest.importorskip("pypdfium2")
    import shutil

    from PIL import Image

    from tests.sheet.raster import rasterise_pdf

    d = tmp_path_factory.mktemp("a4pdf")
    for f in ("sheet.json", "sheet.pdf"):
        shutil.copy(a4 / f, d / f)
    rgb, _ = rasterise_pdf(d / "sheet.pdf", 10.0)
    own = np.asarray(Image.open(a4 / "sheet.png"))
    assert rgb.shape[:2] == own.shape[:2]
    Image.fromarray(rgb).save(d / "sheet.png", dpi=(254, 254))
    return d


@pytest.mark.parametrize("seed", [100])
def test_marks_on_a_rendering_of_the_pdf_are_within_the_bound_or_flagged(a4_pdf, tmp_path,
                                                                         seed):
    """Issue 28 section 4: the print as another rasteriser draws the project's PDF; the
    reference does not know its edges to 50 um (config dots.printed_edge_mm), so a centre
    that depends on them is flagged (before: the axis letter 38 um and a grid number 53 um
    off, unflagged, with poppler's rendering)."""
    res = _measure(a4_pdf, tmp_path / "d", seed)
    for k, (err, why, under) in res.items():
        print(f"{k:12s} {err:.4f} {under!r} {why!r}")
    for k in ON_PRINT:
        err, why, under = res[k]
        assert err < 0.03 or why, (k, err)



@pytest.fixture(scope="module")
def a4_toner(tmp_path_factory, a4):
    """The sheet's own raster with its ink grown about 0.03 mm (a third of a pixel's
    erosion at 254 dpi: toner spread), which the reference does not know."""
    import shutil

    from PIL import Image
    from scipy.ndimage import grey_erosion

    d = tmp_path_factory.mktemp("a4toner")
    for f in ("sheet.json", "sheet.pdf"):
        shutil.copy(a4 / f, d / f)
    own = np.asarray(Image.open(a4 / "sheet.png")).astype(float)
    grown = grey_erosion(own, size=(3, 3, 1))
    Image.fromarray(np.round(0.7 * own + 0.3 * grown).astype(np.uint8)).save(
        d / "sheet.png", dpi=(254, 254))
    return d


def test_a_mark_whose_centre_depends_on_the_print_edges_is_flagged(a4_toner, tmp_path):
    """Toner grew the print 0.03 mm: a blur and a contrast stand for it in the ground
    around a mark on a letter, so the ground cannot pin the edges, and the centre, which
    moves with them (the axis letter 49 um off), is flagged for them (config
    dots.printed_edge_mm, printed_edge_chi2)."""
    res = _measure(a4_toner, tmp_path / "d", 12)
    for k, (err, why, under) in res.items():
        print(f"{k:12s} {err:.4f} {under!r} {why!r}")
    for k in ON_PRINT:
        err, why, _ = res[k]
        assert err < 0.03 or why, (k, err)
    assert "print's edges move" in res["axis letter"][1]
