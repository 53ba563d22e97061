"""Markers the plain detector cannot read are looked for where the sheet's layout puts them
before a photo is refused (measure/aruco.detect_with_layout, issue 37: a real ChArUco photo
showed 17 markers, OpenCV read 6, and the photo was refused for too few)."""

import cv2
import numpy as np

from tests.measure import synth_measure as sm
from vision_cal.measure.aruco import detect_raw, find_sheet_markers
from vision_cal.world.sheet import sheet_to_texture_pixel

PPM = 8.0


def _flip_bits(tex, sheet, marker, cells):
    """Invert the data cells ``cells`` [(row, col)] of ``marker`` in the texture (bits lost
    as blur, glare or a low resolution lose them)."""
    c = np.asarray(marker.corners_mm, float)
    tl, module = c[0], (c[1, 0] - c[0, 0]) / 7.0
    for i, j in cells:
        x0, y0 = tl[0] + (j + 1) * module, tl[1] - (i + 1) * module
        (u0, v0), (u1, v1) = sheet_to_texture_pixel([[x0, y0], [x0 + module, y0 - module]],
                                                    extent_mm=sheet.extent_mm, px_per_mm=PPM)
        sl = (slice(int(round(v0 + 0.5)), int(round(v1 + 0.5))),
              slice(int(round(u0 + 0.5)), int(round(u1 + 0.5))))
        tex[sl] = 255 - tex[sl]


def test_markers_with_lost_bits_are_read_where_the_layout_puts_them():
    """Ten of twelve markers with three bits flipped (beyond what the plain detector
    corrects, within what OpenCV's refinement does at a marker's expected place): the plain
    detection reads two and would refuse the photo; all twelve are found, it is kept."""
    sheet = sm.small_sheet()
    tex = sm.texture(sheet, [], ppm=PPM)
    for m in sheet.markers[2:]:
        _flip_bits(tex, sheet, m, [(0, 1), (2, 2), (4, 3)])
    K, T = sm.view(tilt_deg=12, azimuth_deg=40)
    gray = cv2.cvtColor(sm.photo(sheet, tex, K=K, T=T, rng=3), cv2.COLOR_RGB2GRAY)
    ids, _ = detect_raw(gray, sheet.aruco_dictionary)
    assert len(set(ids.tolist()) & {m.id for m in sheet.markers}) < 4   # refused alone
    found = find_sheet_markers(gray, sheet)
    assert found.reason is None
    assert sorted(found.ids.tolist()) == sorted(m.id for m in sheet.markers)
    # each read where it is: its corners on the layout's homography within a pixel
    H, _ = cv2.findHomography(found.corners_mm.reshape(-1, 2), found.corners_px.reshape(-1, 2))
    back = cv2.perspectiveTransform(found.corners_mm.reshape(-1, 1, 2), H).reshape(-1, 2)
    assert np.abs(back - found.corners_px.reshape(-1, 2)).max() < 1.0
