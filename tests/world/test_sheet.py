"""The printed sheet: layout, pixel convention, markers and ink dots in the texture."""

import cv2
import numpy as np
import pytest

from vision_cal.errors import VisionCalError
from vision_cal.world.sheet import DOT_RGB, make_sheet, sheet_texture, sheet_to_texture_pixel

SMALL = dict(size_mm=(200.0, 150.0), bottom_left_mm=(-100.0, -60.0), marker_mm=20.0,
             grid=(3, 2), margin_mm=10.0)


def _detector():
    p = cv2.aruco.DetectorParameters()
    p.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    p.cornerRefinementWinSize = 4
    p.cornerRefinementMinAccuracy = 0.001
    p.cornerRefinementMaxIterations = 100
    return cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_5X5_100), p)


def test_default_sheet_layout_covers_the_paper():
    sheet = make_sheet()
    x0, y0, x1, y1 = sheet.extent_mm
    assert (x0, y0, x1, y1) == (-297.0, -210.0, 297.0, 210.0)
    assert [m.id for m in sheet.markers] == list(range(35))
    c = np.stack([m.corners_mm for m in sheet.markers])            # (n, 4, 2)
    # TL, TR, BR, BL with y up, 20 mm squares
    np.testing.assert_allclose(c[:, 1, 0] - c[:, 0, 0], 20.0)
    np.testing.assert_allclose(c[:, 0, 1] - c[:, 3, 1], 20.0)
    np.testing.assert_allclose(c[:, 0, 1], c[:, 1, 1])
    np.testing.assert_allclose(c[:, 2, 0], c[:, 1, 0])
    assert c[..., 0].min() == pytest.approx(x0 + 15) and c[..., 0].max() == pytest.approx(x1 - 15)
    assert c[..., 1].min() == pytest.approx(y0 + 15) and c[..., 1].max() == pytest.approx(y1 - 15)
    # any point of the paper has a marker centre within ~ one grid pitch
    centres = c.mean(axis=1)
    g = np.stack(np.meshgrid(np.linspace(x0, x1, 60), np.linspace(y0, y1, 40)), -1).reshape(-1, 2)
    nearest = np.min(np.linalg.norm(g[:, None] - centres[None], axis=2), axis=1)
    assert nearest.max() < 80.0


def test_pixel_convention_round_trip():
    ext = (-100.0, -60.0, 100.0, 90.0)
    xy = np.array([[-100 + 0.5 / 4, 90 - 0.5 / 4], [0.0, 0.0], [99.9, -59.0]])
    uv = sheet_to_texture_pixel(xy, extent_mm=ext, px_per_mm=4.0)
    np.testing.assert_allclose(uv[0], [0.0, 0.0], atol=1e-12)     # centre of pixel (0, 0)
    np.testing.assert_allclose(uv[1], [399.5, 359.5])
    np.testing.assert_allclose(uv[2], [(99.9 + 100) * 4 - 0.5, (90 + 59.0) * 4 - 0.5])


def test_markers_in_texture_are_where_the_sheet_says():
    sheet = make_sheet(**SMALL)
    ppm = 8.0
    tex = sheet_texture(sheet, marks_xy_mm=np.zeros((0, 2)), px_per_mm=ppm, rng=3)
    assert tex.shape == (150 * 8, 200 * 8, 3) and tex.dtype == np.uint8
    corners, ids, _ = _detector().detectMarkers(cv2.cvtColor(tex, cv2.COLOR_RGB2GRAY))
    by_id = sheet.corners_by_id()
    assert sorted(np.ravel(ids).tolist()) == sorted(by_id)
    err = np.concatenate([   # texture px -> mm (the sheet's y is the rows' -v)
        c.reshape(4, 2) - sheet_to_texture_pixel(by_id[int(i)], extent_mm=sheet.extent_mm,
                                                 px_per_mm=ppm)
        for c, i in zip(corners, np.ravel(ids))]) / ppm
    # cornerSubPix on a lone square corner is biased ~0.1 px inwards: 0.0125 mm here
    assert np.sqrt(np.mean(err ** 2)) < 0.02
    assert np.abs(err).max() < 0.04


@pytest.mark.parametrize("ppm", [4.0, 8.0])
def test_ink_dots_are_centred_on_their_marks(ppm):
    sheet = make_sheet(**SMALL)
    rng = np.random.default_rng(5)
    marks = rng.uniform([-60, -30], [60, 60], (12, 2))
    dia = rng.uniform(0.8, 1.6, 12)
    kw = dict(px_per_mm=ppm, grid=False, paper_grain=False, rng=11)
    tex = sheet_texture(sheet, marks_xy_mm=marks, mark_diameters_mm=dia, **kw).astype(float)
    bare = sheet_texture(sheet, marks_xy_mm=np.zeros((0, 2)), **kw).astype(float)
    # ink coverage recovered per pixel from the red channel (opaque alpha blend)
    alpha = (bare[..., 0] - tex[..., 0]) / (bare[..., 0] - DOT_RGB[0])
    uv = sheet_to_texture_pixel(marks, extent_mm=sheet.extent_mm, px_per_mm=ppm)
    vv, uu = np.mgrid[0:tex.shape[0], 0:tex.shape[1]]
    for (u, v), d in zip(uv, dia):
        win = (np.abs(uu - u) < d * ppm) & (np.abs(vv - v) < d * ppm)
        a = alpha[win]
        cu = np.sum(a * uu[win]) / a.sum()
        cv_ = np.sum(a * vv[win]) / a.sum()
        # exact coverage up to uint8 rounding of the edge pixels: 0.02 texture px
        np.testing.assert_allclose([cu, cv_], [u, v], atol=0.02)
        area_mm2 = a.sum() / ppm ** 2
        assert 0.75 < area_mm2 / (np.pi * d * d / 4) < 1.25


def test_texture_refuses_fractional_pixel_count():
    sheet = make_sheet(**SMALL)
    with pytest.raises(VisionCalError, match="px_per_mm"):
        sheet_texture(sheet, marks_xy_mm=[[0.0, 0.0]], px_per_mm=8.33)
