"""--measured-bar-mm: the printer's scale recorded in sheet.json, reported in
calibration.json apart from sheet_affine, and in the summary."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.conftest import ROOT
from vision_cal.commands.main import main
from vision_cal.dataset.session import Sheet
from vision_cal.estimate.document import printer_scale


def _sheet(measured):
    return Sheet("DICT_5X5_100", (), (420.0, 297.0),
                 printed=None if measured is None else {"measured_bar_mm": measured})


def test_printer_scale_from_the_bars_and_what_sheet_affine_leaves():
    assert printer_scale(_sheet(None), []) is None
    sx, sy = 0.998, 1.001
    # a print stretched by (sx, sy) puts an arm at physical a at sheet diag(1/sx, 1/sy) a;
    # the fit only sees the uneven part (here normalised to y = 1)
    pure = [{"name": "sheet_affine", "matrix": [[sy / sx, 0.0], [0.0, 1.0]]}]
    ps = printer_scale(_sheet([99.8, 100.1]), pure)
    assert (ps["x"], ps["y"]) == pytest.approx((sx, sy))
    assert ps["uniform"] == pytest.approx(np.sqrt(sx * sy))
    assert ps["uneven"] == pytest.approx(sx / sy - 1)
    assert ps["sheet_affine_beyond_printer"] == pytest.approx(0.0, abs=1e-12)
    # paper that shrank 0.1 % more in x after printing
    more = [{"name": "sheet_affine", "matrix": [[sy / sx / 0.999, 0.0], [0.0, 1.0]]}]
    assert printer_scale(_sheet([99.8, 100.1]), more)["sheet_affine_beyond_printer"] == \
        pytest.approx(1 / 0.999 - 1)


def test_calibration_reports_the_printer_scale(tmp_path, capsys):
    sheet_dir = tmp_path / "sheet"
    assert main(["sheet", "--size", "A2", "--measured-bar-mm", "99.8", "100.1", "--out",
                 str(sheet_dir), "-q"]) == 0
    doc = json.loads((ROOT / "fixtures" / "paper_sm5" / "session.json").read_text())
    doc["sheet"] = json.loads((sheet_dir / "sheet.json").read_text())
    data = tmp_path / "data"
    data.mkdir()
    (data / "session.json").write_text(json.dumps(doc))
    assert main([str(data), "--out", str(tmp_path / "out")]) == 0
    cal = json.loads((tmp_path / "out" / "calibration.json").read_text())
    ps = cal["printer_scale"]
    assert (ps["x"], ps["y"]) == pytest.approx((0.998, 1.001))
    assert ps["measured_bar_mm"] == [99.8, 100.1]
    u = np.sqrt(0.998 * 1.001)
    assert ps["physical_mm"]["L1_mm"] == pytest.approx(cal["params"]["L1_mm"] * u)
    assert ps["physical_mm"]["L2_mm"] == pytest.approx(cal["params"]["L2_mm"] * u)
    assert "printer scale (measured bars): x 0.99800, y 1.00100" in capsys.readouterr().out
