"""``vision-cal sheet --field``: the marker field an arm camera sees piecewise."""

from __future__ import annotations

import json

import numpy as np

from vision_cal.commands.main import main
from vision_cal.dataset.session import load_sheet_file


def test_field_sheet_covers_the_page_and_reads_back(tmp_path):
    assert main(["sheet", "--size", "A3", "--field", "--out", str(tmp_path), "-q"]) == 0
    doc = json.loads((tmp_path / "sheet.json").read_text())
    assert "grid" not in doc and doc["printed"]["kind"] == "field"
    assert doc["aruco_dictionary"] == "DICT_5X5_1000"
    sheet = load_sheet_file(tmp_path / "sheet.json")
    c = np.array([m.corners_mm.mean(axis=0) for m in sheet.markers])
    # markers every 36 mm (2 sides of 18 mm) in x and y, across the whole A3 page
    xs, ys = np.unique(np.round(c[:, 0], 6)), np.unique(np.round(c[:, 1], 6))
    assert np.allclose(np.diff(xs), 36.0) and np.allclose(np.diff(ys), 36.0)
    assert len(sheet.markers) == len(xs) * len(ys)
    assert xs[0] - 9 < -420 / 2 + 30 and xs[-1] + 9 > 420 / 2 - 30
    # any 100 x 75 mm view (what a camera 150 mm above sees) holds at least 2 whole markers
    rng = np.random.default_rng(2)
    for cx, cy in rng.uniform([-160, -100], [160, 100], (50, 2)):
        inside = [(abs(m.corners_mm[:, 0] - cx) < 50).all() and (abs(m.corners_mm[:, 1] - cy) < 37.5).all()
                  for m in sheet.markers]
        assert sum(inside) >= 2
    assert (tmp_path / "sheet.pdf").stat().st_size > 0


def test_field_that_does_not_fit_names_the_option(tmp_path, capsys):
    assert main(["sheet", "--size", "A4", "--field", "--dictionary", "DICT_4X4_50",
                 "--marker-mm", "10", "--pitch-mm", "20", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--dictionary" in err[0]
