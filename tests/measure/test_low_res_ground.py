"""The unreadable-ground test on a low-resolution JPEG (issue 28 section 4): a held-out
series at about 0.35 mm per pixel (JPEG, a 1 mm grid about 3 px apart) had 19 of 30 marks
left out as "the ground around the mark is not paper and grid lines". The blank paper
JPEG flattens gives a noise the ruled ground around every mark exceeds 2-4 times; the test
is made against the series' own plain ground (``dots.ground_scale``), so it flags ink
under a mark (text, numbers), not pixels.

One photo of the sheet's own raster (A4, 254 dpi, described by nobody: only the photo
tells), 0.35 mm per pixel, JPEG quality 85, with 12 marks on plain paper and grid lines
and 6 on printed text and numbers.
"""

import json

import numpy as np
import pytest

from tests.measure.synth_measure import jpeg_bytes, photo, view, one_mark_session
from vision_cal.config import DEFAULT
from vision_cal.measure.detect import detect_image_bytes
from vision_cal.measure.finish import finish_all
from vision_cal.world.printed import load_printed_sheet, printed_texture
from vision_cal.sheet import make_layout, write_sheet

ON_INK = {"x number": (30.0, 74.1), "y number": (117.8, 20.0), "title": (-80.0, -72.2),
          "instruction": (-60.0, -69.0), "origin text": (-8.0, -2.6),
          "axis letter": (16.8, 0.3)}
PLAIN = {f"p{i}": (x + 0.5, y + 0.5) for i, (x, y) in enumerate(
    [(20, 30), (-40, 20), (50, -30), (-70, 40), (80, 50), (-20, -40), (100, -20), (60, 10),
     (-90, -20), (35, 55), (-55, 60), (110, 60)])}
SIZE = (1000, 750)          # 1400 px focal length at 490 mm: 0.35 mm per pixel


@pytest.fixture(scope="module")
def a4(tmp_path_factory):
    d = tmp_path_factory.mktemp("a4")
    write_sheet(make_layout(size="A4"), d, png_dpi=254)
    return d


def _measure(a4, folder, seed, config=DEFAULT):
    """Per mark name: (error mm, unreliable reason) on one JPEG photo."""
    pr = load_printed_sheet(a4 / "sheet.json")
    rng = np.random.default_rng(seed)
    names = [*ON_INK, *PLAIN]
    xy = np.array([{**ON_INK, **PLAIN}[k] for k in names]) + rng.normal(0, 0.15, (len(names), 2))
    tex = printed_texture(pr, marks_xy_mm=xy, mark_diameters_mm=1.2, rng=seed)
    K, T = view(tilt_deg=15, azimuth_deg=40 + 30 * seed, f_px=1400, dist_mm=490, size=SIZE)
    # a camera integrates over its pixel: the print blurred to about half a pixel
    img = photo(pr.sheet, tex, K=K, T=T, size=SIZE, ppm=pr.px_per_mm, noise=2.0,
                blur_mm=0.2, rng=seed)
    sheet = json.loads((a4 / "sheet.json").read_text())
    sheet.pop("printed")
    session = one_mark_session(folder, sheet, "a.jpg")
    det = detect_image_bytes(jpeg_bytes(img, quality=85), "a.jpg", session)
    (r,), _ = finish_all(session, [det], [False], None, config)
    assert r.status == "ok"
    out = {}
    for k, p in zip(names, xy):
        d = np.hypot(*(r.dots_xy_mm - p).T)
        j = int(np.argmin(d))
        assert d[j] < 1.0, f"{k}: not found"
        out[k] = (float(d[j]), r.dots_unreliable[j])
    return out


def test_a_low_resolution_jpeg_flags_ink_not_pixels(a4, tmp_path):
    """(Seed 4; against the blank paper's noise, ``dots.ground_min_dots`` out of reach,
    4-7 of the 12 plain marks were left out on seeds 1-4.)"""
    res = _measure(a4, tmp_path / "d", 4)
    for k, (err, why) in res.items():
        print(f"{k:12s} {1000 * err:6.1f} um {why!r}")
    plain_flagged = [k for k in PLAIN if res[k][1]]
    assert len(plain_flagged) <= 1, plain_flagged            # was 4-7 of 12
    for k in ON_INK:                                           # ink under it: still told
        err, why = res[k]
        assert err < 0.03 or why, (k, err)


def test_in_a_series_the_photo_before_takes_what_the_plain_ground_hides(a4, tmp_path):
    """In a series, print under a new mark is measured against the photo before (no mark
    there yet) wherever the blank paper's noise would have flagged it, even where the
    series' plain ground does not (``DotMeasurement.suspect``): at 0.35 mm per pixel a grid
    number leaves little more residual than the JPEG'd ground, yet pulls the centre 0.1 mm.
    (The photo before is tried for the marks flagged alone too; the new marks then come
    out as well as plain ones at this resolution, 20-65 um on one photo.)"""
    from vision_cal.dataset.photos import decode_photo
    from vision_cal.measure.finish import finish_image
    from vision_cal.measure.dots import ground_scale
    from vision_cal.measure.previous_photo import PreviousPhoto

    pr = load_printed_sheet(a4 / "sheet.json")
    seed = 8
    rng = np.random.default_rng(seed)
    plain = np.array(list(PLAIN.values())) + rng.normal(0, 0.15, (len(PLAIN), 2))
    ink = np.array(list(ON_INK.values())) + rng.normal(0, 0.15, (len(ON_INK), 2))
    sheet = json.loads((a4 / "sheet.json").read_text())
    sheet.pop("printed")
    folder = tmp_path / "s"
    session = one_mark_session(folder, sheet, "a.jpg")
    K, T = view(tilt_deg=15, azimuth_deg=40 + 30 * seed, f_px=1400, dist_mm=490, size=SIZE)
    shots = []
    for n, marks in enumerate((plain, np.vstack([plain, ink]))):
        tex = printed_texture(pr, marks_xy_mm=marks, mark_diameters_mm=1.2, rng=seed)
        img = photo(pr.sheet, tex, K=K, T=T, size=SIZE, ppm=pr.px_per_mm, noise=2.0,
                    blur_mm=0.2, rng=seed + n)
        data = jpeg_bytes(img, quality=85)
        shots.append((decode_photo(data), detect_image_bytes(data, f"{'ab'[n]}.jpg", session)))
    ra = finish_image(shots[0][1], session)
    rb0 = finish_image(shots[1][1], session)
    g = ground_scale(rb0.dots_bg_residual, rb0.dots_background, rb0.dots_printed_under)
    assert g > 1.5                                   # the JPEG'd ground, not clean paper
    before = PreviousPhoto("a.jpg", shots[0][0].astype(np.float32).sum(axis=2), ra.mapping)
    alone = finish_image(shots[1][1], session, ground_scale=g)
    rb = finish_image(shots[1][1], session, previous=before, ground_scale=g)

    def err(r, p):
        d = np.hypot(*(r.dots_xy_mm - p).T)
        j = int(np.argmin(d))
        assert d[j] < 1.0
        return float(d[j]), r.dots_unreliable[j]

    e_with, e_alone = [], []
    for k, p in zip(ON_INK, ink):
        (e, why), (e0, why0) = err(rb, p), err(alone, p)
        print(f"{k:12s} with the photo before {1000 * e:6.1f} um {why!r:.50} | alone "
              f"{1000 * e0:6.1f} um {why0!r:.50}")
        j = int(np.argmin(np.hypot(*(rb.dots_xy_mm - p).T)))
        assert rb.dots_background[j] == "previous photo" or why, k
        e_with.append(e)
        e_alone.append(e0)
    # the photo before removes the print: the new marks as good as the resolution allows
    # (plain marks: 20-50 um at 0.35 mm per pixel), not 0.05-0.18 mm off
    assert np.sqrt(np.mean(np.square(e_with))) < 0.5 * np.sqrt(np.mean(np.square(e_alone)))
    assert sum(bool(err(rb, p)[1]) for p in plain) <= 1
