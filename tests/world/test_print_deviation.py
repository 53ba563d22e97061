"""The world's printer: a smooth displacement of the printed layer, toner growth."""

import cv2
import numpy as np

from vision_cal.world.print_deviation import PrintField, PrintScene, _similarity_fit
from vision_cal.world.scene import scene_from_dict
from vision_cal.world.sheet import make_sheet, sheet_texture


def _sheet():
    return make_sheet(size_mm=(200.0, 150.0), bottom_left_mm=(-100.0, -75.0), marker_mm=20.0,
                      grid=(3, 2), margin_mm=10.0)


def test_field_has_its_rms_and_no_similarity_at_the_markers():
    sheet = _sheet()
    corners = np.array([m.corners_mm for m in sheet.markers])
    f = PrintScene(0.17, 0.06).field(sheet.extent_mm, corners, seed=5)
    d = f.displacement(f.paper_grid())
    assert abs(np.sqrt(np.mean(np.sum(d**2, axis=1))) - 0.17) < 1e-9
    c = corners.reshape(-1, 2)
    assert np.all(np.abs(_similarity_fit(c, f.displacement(c))) < 1e-9)
    # smooth: neighbouring points 1 mm apart move alike (a printer's field, not noise)
    assert np.abs(f.displacement(c + [1.0, 0]) - f.displacement(c)).max() < 0.02
    # the inverse lands back
    p = f.printed_at(c)
    lx, ly = f.layout_at(p[:, 0], p[:, 1])
    assert np.abs(np.column_stack([lx, ly]) - c).max() < 1e-6
    j = f.to_json([m.id for m in sheet.markers], corners)
    grown = np.array(j["markers"][str(sheet.markers[0].id)])
    assert np.allclose(grown, f.printed_at(corners[0] + 0.06 * np.sign(
        corners[0] - corners[0].mean(axis=0))))


def test_texture_moves_the_print_and_grows_the_toner_not_the_dots():
    sheet = _sheet()
    corners = np.array([m.corners_mm for m in sheet.markers])
    plain = sheet_texture(sheet, marks_xy_mm=[[0.0, 0.0]], px_per_mm=8.0, rng=1,
                          paper_grain=False, grid=False)
    toner = PrintScene(0.0, 0.1).field(sheet.extent_mm, corners, seed=1)
    grown = sheet_texture(sheet, marks_xy_mm=[[0.0, 0.0]], px_per_mm=8.0, rng=1,
                          paper_grain=False, grid=False, print_field=toner)
    black = lambda t: float(np.sum(255.0 - t[..., 1].astype(float)))   # noqa: E731
    # markers' black area: each module region grows; total dark grows by roughly the
    # perimeter x 0.1 mm (at least the outer border: 4 x 20 mm x 0.1 mm per marker)
    assert black(grown) > black(plain) + 0.8 * 6 * 4 * 20 * 0.1 * 64 * 230
    moved = PrintScene(0.3, 0.0).field(sheet.extent_mm, corners, seed=2)
    shifted = sheet_texture(sheet, marks_xy_mm=[[0.0, 0.0]], px_per_mm=8.0, rng=1,
                            paper_grain=False, grid=False, print_field=moved)
    # the pen dot (at the centre, far from markers) is where it was
    r, c = 75 * 8, 100 * 8
    assert np.array_equal(shifted[r - 12:r + 12, c - 12:c + 12], plain[r - 12:r + 12, c - 12:c + 12])
    # a marker's dark centroid moved by the field at its centre
    m = corners[0]
    x0, x1, y0, y1 = m[:, 0].min() - 3, m[:, 0].max() + 3, m[:, 1].min() - 3, m[:, 1].max() + 3
    cs, rs = slice(int((x0 + 100) * 8), int((x1 + 100) * 8)), slice(int((75 - y1) * 8), int((75 - y0) * 8))

    yy, xx = np.mgrid[rs, cs]

    def centroid(t):
        w = 245.0 - t[rs, cs, 1].astype(float)   # paper: 245
        return np.array([np.sum(w * xx), -np.sum(w * yy)]) / w.sum() / 8.0

    d = centroid(shifted) - centroid(plain)
    w = 245.0 - plain[rs, cs, 1].astype(float)   # the ink's mean displacement
    dd = moved.displacement(np.column_stack([(xx.ravel() + 0.5) / 8 - 100,
                                             75 - (yy.ravel() + 0.5) / 8]))
    want = (w.ravel()[:, None] * dd).sum(axis=0) / w.sum()
    assert np.linalg.norm(d - want) < 0.02, (d, want)


def test_scene_reads_the_print_block():
    s = scene_from_dict({"sheet": {"print": {"deviation_rms_mm": 0.17, "toner_mm": 0.06}}})
    assert s.sheet.print.deviation_rms_mm == 0.17 and s.sheet.print.toner_mm == 0.06
    assert scene_from_dict({}).sheet.print is None
    assert scene_from_dict({"photos": {"mode": "survey"}}).photos.mode == "survey"


def _edge_line_corners(gray, corners_mm, extent_mm, ppm):
    """A straight-side reading of each marker in a texture (world-side, for the test): the
    mid-level crossing along each side's normal at 16 points over its middle 76 %, a line
    fitted through them, corner k where side k-1 meets side k; (M, 4, 2) sheet mm."""
    x0, _, _, y1 = extent_mm

    def to_px(q):
        return np.column_stack([(q[:, 0] - x0) * ppm - 0.5, (y1 - q[:, 1]) * ppm - 0.5])

    out = []
    for P in corners_mm:
        pp, lines = to_px(P), []
        for k in range(4):
            a, b = pp[k], pp[(k + 1) % 4]
            d = (b - a) / np.linalg.norm(b - a)
            n = np.array([d[1], -d[0]])
            n = n if np.dot((a + b) / 2 - pp.mean(axis=0), n) > 0 else -n    # outward
            pts = []
            for t in np.linspace(0.12, 0.88, 16):
                q, s = a + t * (b - a), np.linspace(-4.0, 4.0, 161)
                prof = cv2.remap(gray, (q[0] + s * n[0]).astype(np.float32)[None],
                                 (q[1] + s * n[1]).astype(np.float32)[None], cv2.INTER_CUBIC)[0]
                lvl = 0.5 * (prof[:10].mean() + prof[-10:].mean())
                i = int(np.argmax(prof >= lvl))
                f = (lvl - prof[i - 1]) / (prof[i] - prof[i - 1])
                pts.append(q + (s[i - 1] + f * (s[1] - s[0])) * n)
            pts = np.array(pts)
            m = pts.mean(axis=0)
            lines.append((m, np.linalg.svd(pts - m)[2][0]))
        c = []
        for k in range(4):
            (p1, d1), (p2, d2) = lines[k - 1], lines[k]
            c.append(p1 + np.linalg.solve(np.column_stack([d1, -d2]), p2 - p1)[0] * d1)
        c = np.array(c)
        out.append(np.column_stack([x0 + (c[:, 0] + 0.5) / ppm, y1 - (c[:, 1] + 0.5) / ppm]))
    return np.array(out)


def test_straight_side_corners_are_what_the_texture_s_straight_sides_give():
    """A feed wave curves a marker's sides: their straight fits meet away from the corner
    points (seed 2871 of renders/printed_off_six.yaml read that as a 1.4e-4 shear).
    truth.json ``markers_straight_sides`` is what the texture's straight sides give;
    ``markers`` (the points) is not, by ~0.4 h^2 times the curvature."""
    sheet = _sheet()
    corners = np.array([m.corners_mm for m in sheet.markers])
    # a short strong wave along the feed: curvature (2 pi / 60)^2 0.3 = 3.3e-3 /mm
    f = PrintField(sheet.extent_mm, {"a1": 1.0, "lam1": 60.0, "ph1": 0.3, "a2": 0.0,
                                     "lam2": 100.0, "ph2": 0.0, "b": 0.0, "s": 0.0},
                   np.zeros(4), 0.3, 0.0)
    ppm = 8.0
    tex = sheet_texture(sheet, marks_xy_mm=np.zeros((0, 2)), px_per_mm=ppm, rng=1,
                        paper_grain=False, grid=False, print_field=f)
    read = _edge_line_corners(cv2.cvtColor(tex, cv2.COLOR_RGB2GRAY).astype(np.float32),
                              f.printed_corners(corners), sheet.extent_mm, ppm)
    straight, points = f.straight_side_corners(corners), f.printed_corners(corners)
    assert np.abs(straight - points).max() > 0.05            # the curvature shows
    assert np.abs(read - straight).max() < 0.01, np.abs(read - straight).max()
    assert np.abs(read - points).max() > 0.04
    j = f.to_json([m.id for m in sheet.markers], corners)
    assert np.allclose(j["markers_straight_sides"][str(sheet.markers[0].id)], straight[0])
    assert abs(j["straight_side_rms_mm"]
               - np.sqrt(np.mean(np.sum((straight - points) ** 2, axis=2)))) < 1e-12
    # an affine field (the skew alone) keeps the sides straight: the two agree
    g = PrintField(sheet.extent_mm, {"a1": 0.0, "lam1": 60.0, "ph1": 0.0, "a2": 0.0,
                                     "lam2": 100.0, "ph2": 0.0, "b": 0.0, "s": 1.0},
                   np.zeros(4), 0.3, 0.06)
    assert np.abs(g.straight_side_corners(corners) - g.printed_corners(corners)).max() < 1e-9
