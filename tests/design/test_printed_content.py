"""The informative plan keeps its marks off the sheet's printed content (issue 18 section 1):
the axes, their arrows and letters and "origin (0, 0)" of a `vision-cal sheet` are
obstacles like the markers."""

import json

import numpy as np

from vision_cal.dataset.session import load_sheet_file
from vision_cal.design.stage import drawable_sheet, with_printed_content
from vision_cal.plan.calibration_plan import sheet_clearance_mm
from vision_cal.sheet import make_layout, write_sheet


def test_printed_content_is_an_obstacle(tmp_path):
    write_sheet(make_layout(size="A3"), tmp_path)
    raw = json.loads((tmp_path / "sheet.json").read_text())
    sheet = drawable_sheet(load_sheet_file(tmp_path / "sheet.json"), raw)
    kept = with_printed_content(sheet)
    on_print = np.array([[6.0, 0.0], [0.0, 6.0], [13.5, 0.0], [-8.0, -2.6]])   # axes, arrow, text
    plain = np.array([[40.5, 60.5], [-60.5, 30.5]])
    assert np.all(sheet_clearance_mm(sheet, on_print) > 5.0)     # without: free paper
    assert np.all(sheet_clearance_mm(kept, on_print) <= 0.0)     # with: on an obstacle
    assert np.all(sheet_clearance_mm(kept, plain) > 20.0)         # plain paper stays free
    # a sheet nobody describes stays as it is
    raw["printed"]["generator"] = "another program"
    (tmp_path / "other.json").write_text(json.dumps(raw))
    other = load_sheet_file(tmp_path / "other.json")
    assert with_printed_content(other) is other
