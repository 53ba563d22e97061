"""``design --pilot`` refuses a calibration made on another sheet (issue 19): calibration.json
records which sheet it was measured on."""

from __future__ import annotations

import json
from pathlib import Path

from tests.commands.test_trust import assert_one_line, cli, snapshot
from tests.design.conftest import ROBOT, border_sheet


def test_pilot_calibration_records_its_sheet_and_another_sheet_is_refused(
        tmp_path, capsys, informative_dir, pilot_dir, sheet_json):
    s = json.loads((informative_dir / "session.json").read_text())
    cal = s["design"]["pilot_calibration"]
    doc = json.loads(Path(cal).read_text())
    assert doc["sheet"]["n_markers"] == len(border_sheet().markers)
    other = tmp_path / "other.json"
    other.write_text(json.dumps(border_sheet(size_mm=(420.0, 297.0), marker_mm=24.0).to_json()))
    out = tmp_path / "plan"
    before = snapshot(tmp_path)
    rc, _, err = cli(["design", ROBOT, "--sheet", other, "--out", out, "--pilot", cal], capsys)
    assert rc == 2
    assert_one_line(err, cal, "sheet", "another sheet", str(other))
    assert snapshot(tmp_path) == before and not out.exists()
    # the sheet it was calibrated on is accepted
    rc, _, err = cli(["design", ROBOT, "--sheet", sheet_json, "--out", out, "--pilot", cal,
                      "-q"], capsys)
    assert rc == 0, err
