"""design --survey: the sheet as surveyed goes with the plan, checked before anything is
written (#28)."""

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from tests.design.conftest import ROBOT, border_sheet
from vision_cal.actions import design as design_action
from vision_cal.commands.main import main
from vision_cal.measure.asprinted import AsPrinted, gauge_projector
from vision_cal.measure.survey import FORMAT

#: what a survey that claims its field records (issue 37): significant, and its halves agree
CLAIMED = {"significance": {"chi2_dof": 40.0, "dof": 60, "p_value": 0.0},
           "replication": {"status": "agree", "chi2_dof": 0.9}}


def _survey(sheet, shift_mm=0.0, **blocks) -> dict:
    """A survey.json of ``sheet`` (declared ``shift_mm`` off it): a 0.1 mm wave in the
    survey's gauge (no similarity to the declared layout)."""
    ids = np.array([m.id for m in sheet.markers])
    dec = np.array([m.corners_mm for m in sheet.markers], float) + shift_mm
    rel = np.ones(dec.shape[:2], bool)
    wave = 0.1 * np.column_stack([np.sin(dec[..., 1].ravel() / 40.0),
                                  np.cos(dec[..., 0].ravel() / 50.0)])
    dev = (gauge_projector(dec, rel) @ wave.ravel()).reshape(dec.shape)
    ap = AsPrinted(ids, dec, dec + dev, np.full(dec.shape, 0.01), rel,
                   np.eye(3), np.zeros(5), (100, 100), False, (), (), (), 6, "survey")
    return {"format": FORMAT, "as_printed": {**ap.to_json(), **CLAIMED, **blocks}}


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


def test_design_leaves_a_survey_that_does_not_replicate_and_says_so(tmp_path, capsys,
                                                                     monkeypatch):
    """Issue 37: a survey beside the sheet whose halves disagree is not copied to the plan
    (calibrate would apply it), and one line says why. The plan itself is not what is
    tested: the design stage is a stub writing session.json."""
    def stub(robot, sheet, out, **kw):
        Path(out).mkdir(parents=True, exist_ok=True)
        (Path(out) / "session.json").write_text("{}")
        return SimpleNamespace(stage="pilot", n_marks=3, duration_s=1.0,
                               info={"worst_case_clearance_mm": 5.0, "placements_checked": 1},
                               session_path=Path(out) / "session.json", trajectory_path=None,
                               program_path=None)

    monkeypatch.setattr(design_action, "design_stage", stub)
    sheet = border_sheet()
    (tmp_path / "s").mkdir()
    (tmp_path / "s" / "sheet.json").write_text(json.dumps(sheet.to_json()))
    bad = {"status": "disagree", "reason": "the halves' fields differ by 0.5 mm RMS"}
    (tmp_path / "s" / "survey.json").write_text(json.dumps(_survey(sheet, replication=bad)))
    assert main(["design", str(ROBOT), "--sheet", str(tmp_path / "s" / "sheet.json"),
                 "--out", str(tmp_path / "p"), "--program", "none"]) == 0
    assert (tmp_path / "p" / "session.json").is_file()
    assert not (tmp_path / "p" / "survey.json").exists()
    said = [line for line in capsys.readouterr().out.splitlines() if "surveyed" in line]
    assert len(said) == 1 and said[0].startswith("not applying the sheet as surveyed")
    assert "the halves' fields differ by 0.5 mm RMS" in said[0]
