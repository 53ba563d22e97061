"""design --survey: the sheet as surveyed goes with the plan, checked before anything is
written (#28)."""

import json

import numpy as np

from tests.design.conftest import ROBOT, border_sheet
from vision_cal.commands.main import main
from vision_cal.measure.asprinted import AsPrinted
from vision_cal.measure.survey import FORMAT


def _survey(sheet, shift_mm=0.0) -> dict:
    ids = np.array([m.id for m in sheet.markers])
    dec = np.array([m.corners_mm for m in sheet.markers], float) + shift_mm
    ap = AsPrinted(ids, dec, dec + 0.1, np.full(dec.shape, 0.01), np.ones(dec.shape[:2], bool),
                   np.eye(3), np.zeros(5), (100, 100), False, (), (), (), 6, "survey")
    return {"format": FORMAT, "as_printed": ap.to_json()}


def test_design_takes_the_survey_beside_the_sheet(tmp_path):
    sheet = border_sheet()
    (tmp_path / "s").mkdir()
    (tmp_path / "s" / "sheet.json").write_text(json.dumps(sheet.to_json()))
    (tmp_path / "s" / "survey.json").write_text(json.dumps(_survey(sheet)))
    assert main(["design", str(ROBOT), "--sheet", str(tmp_path / "s" / "sheet.json"),
                 "--out", str(tmp_path / "p"), "-q", "--program", "none"]) == 0
    assert json.loads((tmp_path / "p" / "survey.json").read_text()) == _survey(sheet)


def test_design_refuses_a_survey_of_another_sheet_before_writing(tmp_path, capsys):
    sheet = border_sheet()
    (tmp_path / "sheet.json").write_text(json.dumps(sheet.to_json()))
    (tmp_path / "other.json").write_text(json.dumps(_survey(sheet, shift_mm=2.0)))
    assert main(["design", str(ROBOT), "--sheet", str(tmp_path / "sheet.json"), "--survey",
                 str(tmp_path / "other.json"), "--out", str(tmp_path / "p"), "-q"]) == 2
    assert "as_printed.markers[0].declared_mm" in capsys.readouterr().err
    assert not (tmp_path / "p" / "session.json").exists()
