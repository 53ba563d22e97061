"""A survey read back is checked like any input, and applied only when it claims its print
field (issue 37): its sheet, its gauge, its stds and deviations; a failed survey, or one
whose field does not replicate, is not applied by calibrate or design (one line each)."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tests.measure import synth_measure as sm
from vision_cal.actions.calibrate import SurveyNotApplied
from vision_cal.commands.main import main
from vision_cal.errors import VisionCalError
from vision_cal.measure.asprinted import AsPrinted, gauge_projector
from vision_cal.measure.replicate import FAILED, NOT_REPLICATED, NOT_SIGNIFICANT
from vision_cal.measure.survey import FORMAT, applicable, load_survey

ROOT = Path(__file__).resolve().parents[2]
AGREED = {"status": "agree", "reason": None, "chi2_dof": 0.9}
SIGNIFICANT = {"chi2_dof": 40.0, "dof": 40, "p_value": 0.0}


def _survey(sheet, *, scale=1.0, replication=AGREED, significance=SIGNIFICANT,
            std=0.01) -> dict:
    """survey.json of ``sheet``: a 0.15 mm wave in the survey's gauge, its corners then
    scaled by ``scale`` about the sheet's origin (as an editor would)."""
    ids = np.array([m.id for m in sheet.markers])
    dec = np.array([m.corners_mm for m in sheet.markers], float)
    rel = np.ones(dec.shape[:2], bool)
    wave = 0.15 * np.column_stack([np.sin(dec[..., 1].ravel() / 30.0),
                                   np.cos(dec[..., 0].ravel() / 45.0)])
    dev = (gauge_projector(dec, rel) @ wave.ravel()).reshape(dec.shape)
    ap = AsPrinted(ids, dec, (dec + dev) * scale, np.full(dec.shape, std), rel,
                   np.array([[1400.0, 0, 499.5], [0, 1400.0, 374.5], [0, 0, 1]]), np.zeros(5),
                   (1000, 750), True, (), (), (), 6, "survey",
                   replication=replication, significance=significance)
    return {"format": FORMAT, "sheet": {"sheet_id": None}, "as_printed": ap.to_json()}


def _write(path, doc) -> Path:
    path.write_text(json.dumps(doc))
    return path


def test_a_survey_scaled_by_1_01_is_refused_naming_file_and_field(tmp_path, capsys):
    """Every corner scaled by 1.01 (the issue: taken by calibrate --survey, L1 3.4 mm long):
    refused before anything is measured or written, exit 2, the file and the field named."""
    sheet = sm.small_sheet()
    f = _write(tmp_path / "scaled.json", _survey(sheet, scale=1.01))
    (tmp_path / "data").mkdir()
    assert main(["calibrate", str(tmp_path / "data"), "--survey", str(f),
                 "--out", str(tmp_path / "out"), "-q"]) == 2
    err = capsys.readouterr().err
    assert str(f) in err and "as_printed.markers[].corners_mm" in err
    assert "scaled 1.01000" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out" / "calibration.json").exists()
    # the same layout in its gauge is taken
    assert load_survey(_write(tmp_path / "ok.json", _survey(sheet)), sheet).source == "survey"


@pytest.mark.parametrize("change, field", [
    ("std0", "as_printed.markers[0].std_mm"),
    ("far", "as_printed.markers[1].corners_mm"),
    ("sheet_id", "sheet.sheet_id"),
])
def test_implausible_surveys_are_refused_naming_the_field(tmp_path, change, field):
    """A released corner with no std (or one beyond the prior), a corner further off than
    any printer, a survey of another sheet_id."""
    sheet = sm.small_sheet()
    doc = _survey(sheet)
    if change == "std0":
        doc["as_printed"]["markers"][0]["std_mm"][2] = [0.0, 0.0]
    elif change == "far":
        doc["as_printed"]["markers"][1]["corners_mm"][0][0] += 6.0
    else:
        doc["sheet"]["sheet_id"] = "another-sheet"
        sheet = type(sheet)(**{**sheet.__dict__, "printed": {"sheet_id": "this-sheet"}})
    with pytest.raises(VisionCalError, match=field.replace("[", r"\[").replace("]", r"\]")):
        load_survey(_write(tmp_path / "s.json", doc), sheet)


def test_only_a_survey_that_claims_its_field_is_applicable(tmp_path):
    """Replicated and significant: applied; halves that disagree, a field not significant,
    a survey written before replication (neither block), a failed survey (no layout): not."""
    sheet = sm.small_sheet()
    assert applicable(_write(tmp_path / "a.json", _survey(sheet))).applied
    bad = {"status": "disagree", "reason": "the halves' fields differ by 0.5 mm RMS"}
    c = applicable(_write(tmp_path / "b.json", _survey(sheet, replication=bad)))
    assert c.status == NOT_REPLICATED and "differ by 0.5 mm" in c.reason
    c = applicable(_write(tmp_path / "c.json", _survey(
        sheet, significance={"chi2_dof": 1.1, "dof": 40, "p_value": 0.3})))
    assert c.status == NOT_SIGNIFICANT
    c = applicable(_write(tmp_path / "d.json", _survey(sheet, replication=None,
                                                       significance=None)))
    assert c.status == NOT_REPLICATED
    failed = {"format": FORMAT, "as_printed": None,
              "print": {"claimed": False, "status": FAILED,
                        "reason": "the bundle adjustment stopped at its evaluation limit"}}
    f = _write(tmp_path / "e.json", failed)
    c = applicable(f)
    assert c.status == FAILED and "evaluation limit" in c.reason
    with pytest.raises(VisionCalError, match="as_printed"):
        load_survey(f, sheet)


def test_calibrate_says_in_one_line_that_a_survey_beside_it_is_not_applied(tmp_path, capsys):
    """A survey whose halves disagree, in the dataset folder: the folder is calibrated
    without it, and one line says so (marks measured by other means: no photos)."""
    data = tmp_path / "data"
    shutil.copytree(ROOT / "fixtures" / "paper_sm5", data)
    bad = {"status": "disagree", "reason": "the halves' fields differ by 0.5 mm RMS"}
    _write(data / "survey.json", _survey(sm.small_sheet(), replication=bad))
    assert main(["calibrate", str(data), "--out", str(tmp_path / "out"), "-q"]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if "surveyed" in line]
    assert len(err) == 1
    assert err[0].startswith(f"not applying the sheet as surveyed ({data / 'survey.json'}): "
                             "not replicated: the print field (")
    assert err[0].endswith("does not replicate: the halves' fields differ by 0.5 mm RMS")
    assert (tmp_path / "out" / "calibration.json").is_file()
    SurveyNotApplied(data / "survey.json", FAILED, "stopped").show(quiet=True)
    assert "failed: stopped" in capsys.readouterr().err


def test_a_survey_whose_solve_stopped_is_a_failure_with_no_layout(tmp_path, capsys):
    """The bundle adjustment stopped on its evaluation limit: survey.json says ``failed``
    with the reason, writes no layout, no lens and no residuals, the command exits 1 saying
    so even when quiet, and the file is never applied."""
    from dataclasses import replace

    from vision_cal.actions.survey import SurveyOutcome
    from vision_cal.config import DEFAULT
    from vision_cal.measure.replicate import claim_of
    from vision_cal.measure.survey import survey_document

    sheet = sm.small_sheet()
    ap = AsPrinted.from_json(_survey(sheet)["as_printed"])
    ap = replace(ap, stopped="the bundle adjustment stopped at its evaluation limit (100) "
                             "before converging (100 evaluations)")
    doc = survey_document(tmp_path / "sheet.json", sheet, [], ap, claim_of(ap), [], DEFAULT)
    assert doc["verdict"]["status"] == "failed" and "evaluation limit" in doc["verdict"]["text"]
    assert doc["as_printed"] is None and doc["lens"] is None
    assert doc["print"]["claimed"] is False and doc["print"]["status"] == FAILED
    assert doc["solve"]["status"] == "stopped"
    f = _write(tmp_path / "survey.json", doc)
    assert SurveyOutcome(doc, f).show(quiet=True) == 1
    assert capsys.readouterr().err.startswith(f"{f}: failed: the bundle adjustment stopped")
    assert applicable(f).status == FAILED
