"""The closed loop on the small scene: the calibrated plan hits, the nominal one misses."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from vision_cal.dataset.calibration import load_calibration
from vision_cal.dataset.csvio import read_plan, read_targets
from vision_cal.actions.loop import format_table, run_loop
from vision_cal.world.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def loop(tmp_path_factory):
    out = tmp_path_factory.mktemp("loop")
    doc, run = run_loop(ROOT / "renders" / "small.yaml", out_dir=out, jobs=1)
    return out, doc, run


def _prediction_cov(run, q, s):
    """(N, 2, 2) covariance of the calibrated model's pen position at commands q, s (mm^2):
    J C J^T with the final fit's parameter covariance."""
    fit = run.diagnosis.final_fit
    J = fit.model.jacobian(q, s)
    return np.einsum("nip,pq,njq->nij", J, fit.cov, J)


def test_table3_before_and_after_from_photographs(loop):
    """The after RMS against what the calibration itself says it should be: per target the
    calibrated model's prediction covariance, the robot's repeatability (twice: the
    calibration marks had it too, already in the covariance; the new mark has its own) and
    the after photo's measurement covariance; the mean square error over n targets is then
    a chi-square with 2n dof scaled by their mean variance: bound at its 1 - 1e-4 quantile."""
    from scipy import stats

    out, doc, run = loop
    s = doc["summary"]
    assert s["after"]["n_measured"] >= 0.8 * s["n_targets"]
    assert s["before"]["rms_mm"] > 2.0          # the nominal model misses by millimetres
    scene = load_scene(ROOT / "renders" / "small.yaml")
    rep = scene.robot.repeatability_mm
    meas = json.loads((out / "measure_after" / "measurement.json").read_text())["marks"]
    pid, q, app = read_plan(out / "plan_after.csv")
    pred = dict(zip(pid, np.trace(_prediction_cov(run, q, app), axis1=1, axis2=2)))
    var = [pred[r["id"]] + 2 * rep**2 + np.trace(meas[r["id"]]["cov_mm2"])
           for r in doc["targets"] if r["after_error_mm"] is not None]
    n = len(var)
    bound = np.sqrt(np.mean(var) / 2 * stats.chi2.ppf(1 - 1e-4, 2 * n) / n)
    assert s["after"]["rms_mm"] < bound, (s["after"]["rms_mm"], bound)
    assert s["after"]["rms_mm"] < s["before"]["rms_mm"] / 20
    table = format_table(doc)
    assert "before: RMS" in table and "after: RMS" in table
    assert (out / "loop.json").exists() and (out / "plan_after.csv").exists()


def test_calibrated_plan_brings_the_true_robot_to_its_targets(loop):
    """`vision-cal plan` on the calibration we wrote: the true robot (the world's own code,
    hidden effects included) lands on every target within the calibration's own prediction
    uncertainty (Mahalanobis distance under the chi-square 1 - 1e-4 quantile, Bonferroni
    over the targets), before any camera is involved."""
    from scipy import stats

    out, _, run = loop
    truth = load_scene(ROOT / "renders" / "small.yaml").robot.true_robot
    ids, xy = read_targets(out / "targets.csv")
    pid, q, s = read_plan(out / "plan_after.csv")
    t = dict(zip(ids, xy))
    err = truth.pen_mm(q, s) - np.array([t[i] for i in pid])
    cov = _prediction_cov(run, q, s)
    d2 = np.einsum("ni,nij,nj->n", err, np.linalg.inv(cov), err)
    assert len(pid) >= len(ids) - 2
    assert np.all(d2 < stats.chi2.ppf(1 - 1e-4 / len(pid), 2)), (d2, np.hypot(*err.T))
    model, _ = load_calibration(run.out_path)
    assert [e.name for e in model.effects] == ["joint_backlash"]


def test_the_loop_calibration_reads_back_unchanged(loop):
    """calibration.json of a run with photos (lens, images, marks with their photos)
    round-trips through the typed result."""
    from vision_cal.dataset.calibration_result import CalibrationResult

    out, doc, run = loop
    path = next(out.rglob("calibration.json"))
    written = json.loads(path.read_text())
    assert written["images"] and CalibrationResult.from_json(written).to_json() == written


def test_loop_report_headline_photos_once_and_linked(loop):
    """The report of a loop: the headline carries the loop's target figures and
    calibration.json's RMS; every measured photo is embedded once (within the budget) and
    links to its full-size file; nothing is written into the input folder."""
    import json
    import os
    import re

    from vision_cal.report import html as rh

    out, doc, run = loop
    before = sorted(p.name for p in (out / "session").iterdir())
    page_path = rh.write_report(run.out_path, out / "calibration", loop=out / "loop.json")
    assert sorted(p.name for p in (out / "session").iterdir()) == before
    rep = json.loads((out / "calibration" / "report.json").read_text())
    cal = json.loads(run.out_path.read_text())
    acc = {a["key"]: a for a in rep["headline"]["accuracy"]}
    assert acc["residual_rms_mm"]["after_mm"] == cal["residual_rms_mm"]["final_model"]
    assert acc["validation_rms_mm"]["after_mm"] == cal["validation_rms_mm"]["final_model"]
    assert acc["loop.summary"]["after_mm"] == doc["summary"]["after"]["rms_mm"]
    assert acc["loop.summary"]["before_mm"] == doc["summary"]["before"]["rms_mm"]
    page = page_path.read_text()
    ok = [im for im in cal["images"] if im["status"] == "ok"]
    jpegs = re.findall(r"src='data:image/jpeg;base64,([^']*)'", page)
    assert len(jpegs) == min(len(ok), rh.MAX_PHOTOS)
    assert page.count("data:image/jpeg") == len(jpegs)   # once each, nowhere else
    assert sum(len(j) for j in jpegs) <= rh.PHOTO_BUDGET_BYTES
    links = re.findall(r"<a href='([^']*)'>full size</a>", page)
    assert len(links) == len(jpegs)
    for link in links:
        assert (page_path.parent / link).is_file(), link
        assert not os.path.isabs(link)


def test_landing_note_says_where_the_pen_went(loop):
    from vision_cal.actions.loop import landing_note
    from vision_cal.plan.compensate import PlannedTarget

    _, _, run = loop
    sheet = run.session.sheet

    class At:
        def __init__(self, xy):
            self.xy = np.array([xy], float)

        def predict(self, q, s):
            return self.xy

    x0, y0, x1, y1 = sheet.extent_mm
    p = PlannedTarget("t", (0.0, 0.0), (0.0, 0.0), (1, 1))
    assert landing_note(sheet, At([x1 + 5, y0 + 10]), p).startswith("off the paper")
    c = np.asarray(sheet.markers[0].corners_mm, float).mean(axis=0)
    assert landing_note(sheet, At(c), p).startswith("on a printed marker")
    free = [0.5 * (x0 + x1), 0.5 * (y0 + y1)]
    from vision_cal.plan.calibration_plan import sheet_clearance_mm

    if sheet_clearance_mm(sheet, np.array([free]))[0] > 0:
        assert landing_note(sheet, At(free), p).startswith("not measured")


@pytest.mark.parametrize("status, used", [("not significant", True), ("applied", True),
                                          ("not replicated", False), ("failed", False),
                                          ("raises", False)])
def test_a_survey_block_surveys_first_and_the_calibration_uses_what_measured_the_print(
        tmp_path, monkeypatch, status, used):
    """The scene's ``survey`` block: the blank sheet of the same world is rendered into
    survey_photos/ before the session, surveyed into survey/survey.json and passed to the
    calibration when it measured the print (a field applied, or the print found on its
    layout), never when it did not (not replicated, failed, no survey at all); loop.json's
    block and the console line say which. The renders, the survey and the calibration
    are stand-ins: what is checked is what the loop passes between them."""
    from types import SimpleNamespace

    from vision_cal.errors import VisionCalError
    from vision_cal.measure.replicate import Claim
    from vision_cal.world.scene import scene_from_dict
    from vision_cal.actions import loop as lp

    rendered, calibrated = [], []

    def render(scene, out_dir, **kw):
        rendered.append((scene, Path(out_dir).name))
        Path(out_dir).mkdir(parents=True)
        return Path(out_dir)

    def survey(photos, sheet_json, out_dir):
        assert Path(photos).name == "survey_photos" and Path(sheet_json).parent == photos
        if status == "raises":
            raise VisionCalError("2 usable photo(s) from fewer than 3 camera places")
        return {"photos": [{"status": "ok"}] * 6, "verdict": {"status": "no field",
                                                              "text": f"survey {status}"}}

    def calibrate(folder, *, out_dir, survey=None, **kw):
        calibrated.append(survey)
        return SimpleNamespace(document={"marks": {}})

    monkeypatch.setattr(lp, "render_dataset", render)
    monkeypatch.setattr(lp, "run_survey", survey)
    monkeypatch.setattr(lp, "applicable", lambda path: Claim(status, "why"))
    monkeypatch.setattr(lp, "calibrate_dataset", calibrate)
    scene = scene_from_dict({"seed": 4, "survey": {"n_views": 6, "tilt_deg": [10, 30]}})
    _, block = lp._calibrate_scene(scene, tmp_path, jobs=1, render_jobs=2, progress=False,
                                   photographer=None, stages={})
    (sv, where), (session, _) = rendered
    assert where == "survey_photos" and sv.photos.mode == "survey"
    assert (sv.seed, sv.sheet, sv.camera.n_views, sv.camera.tilt_deg) == (
        4, scene.sheet, 6, (10.0, 30.0))
    assert session is scene
    assert block["used"] is used
    assert calibrated == [str(tmp_path / "survey" / "survey.json") if used else None]
    assert block["status"] == ("failed" if status == "raises" else status)
    line = lp.format_table({"targets": [], "summary": {
        "n_targets": 0, "before": {"rms_mm": None}, "after": {"rms_mm": None}},
        "survey": block})
    assert ("used by the calibration" in line) is used and "survey of the blank sheet" in line
    from vision_cal.report.html import _targets_html   # the report's Table 3 says it too

    row = {"id": "t", "target_mm": [0.0, 0.0], "before_error_mm": 1.0, "after_error_mm": 0.01}
    page = "".join(_targets_html({"loop": {"targets": [row], "survey": block}}))
    assert ("used by the calibration" in page) is used and "survey of the blank sheet" in page

    rendered.clear(), calibrated.clear()
    _, block = lp._calibrate_scene(scene_from_dict({}), tmp_path / "none", jobs=1,
                                   render_jobs=2, progress=False, photographer=None,
                                   stages={})
    assert block is None and calibrated == [None] and [w for _, w in rendered] == ["session"]
