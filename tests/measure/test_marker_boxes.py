"""The one owner of the marker boxes kept clear of pen marks."""

import numpy as np

from vision_cal.dataset.session import Sheet, SheetMarker
from vision_cal.dataset.marker_geometry import marker_boxes_mm, quiet_boxes_mm


def _sheet(printed=None):
    # a 30 mm marker with its bottom-left corner at (10, 20), corners TL TR BR BL (y up)
    c = np.array([[10, 50], [40, 50], [40, 20], [10, 20]], float)
    return Sheet("DICT_5X5_100", (SheetMarker(3, c),), (200.0, 100.0), printed=printed)


def test_boxes_by_hand():
    s = _sheet()
    np.testing.assert_array_equal(marker_boxes_mm(s), [[10, 20, 40, 50]])
    np.testing.assert_array_equal(marker_boxes_mm(s, 2.5), [[7.5, 17.5, 42.5, 52.5]])
    # DICT_5X5: 5 bits + 2 border modules = 7 modules of 30/7 mm; 2 quiet modules printed
    q = 2 * 30.0 / 7
    np.testing.assert_allclose(quiet_boxes_mm(_sheet({"quiet_zone_modules": 2})),
                               [[10 - q, 20 - q, 40 + q, 50 + q]])
