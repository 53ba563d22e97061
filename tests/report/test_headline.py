"""The report's headline, verdict and actions: figures are calibration.json's, never
recomputed; the verdict follows the identifiability diagnostics and the held-out RMS."""

from __future__ import annotations

import copy
import json
import math

import pytest

from vision_cal.commands.main import main
from vision_cal.estimate.verdict import R95_PER_RMS, Verdict, judge
from vision_cal.report import headline as hl
from vision_cal.report import plots


@pytest.fixture(scope="module")
def out(tmp_path_factory, paper_folder):
    o = tmp_path_factory.mktemp("head")
    assert main([str(paper_folder), "--out", str(o), "--report", "-q"]) == 0
    return o


@pytest.fixture()
def doc(out):
    return json.loads((out / "calibration.json").read_text())


def test_headline_figures_are_calibration_json_figures(out, doc):
    rep = json.loads((out / "report.json").read_text())
    acc = {a["key"]: a for a in rep["headline"]["accuracy"]}
    for key in ("residual_rms_mm", "validation_rms_mm"):
        assert acc[key]["before_mm"] == doc[key]["base_model"]
        assert acc[key]["after_mm"] == doc[key]["final_model"]
    # the same on a document where before and after differ (the paper's do not)
    d = copy.deepcopy(doc)
    d["residual_rms_mm"] = {"base_model": 0.25, "final_model": 0.011}
    d["validation_rms_mm"] = {"base_model": 0.27, "final_model": 0.013, "kind": "validation marks"}
    acc = {a["key"]: a for a in hl.headline(d)["accuracy"]}
    assert (acc["residual_rms_mm"]["before_mm"], acc["residual_rms_mm"]["after_mm"]) == (0.25, 0.011)
    assert (acc["validation_rms_mm"]["before_mm"],
            acc["validation_rms_mm"]["after_mm"]) == (0.27, 0.013)
    # the paper's five marks cannot separate backlash (one approach direction) from the
    # base model: "not reliable", with the plan change that fixes it; without that
    # diagnostic, five marks are still too few: "use with care", with the 95 % figure
    v = rep["headline"]["verdict"]
    assert v["status"] == doc["verdict"]["status"]     # the document's block, read
    ni = doc["identifiability"]["not_identifiable"]
    if ni:
        assert v["status"] == "not reliable" and ni[0]["fix"] in v["text"]
    else:
        assert v["status"] == "check"
    d = copy.deepcopy(doc)
    d["identifiability"]["not_identifiable"] = []
    d["effects"] = []
    v = judge(d)
    assert v.status == "check" and "5 fitted marks" in v.text
    assert v.expected_target_error_mm == pytest.approx(
        R95_PER_RMS * doc["validation_rms_mm"]["final_model"])


def test_r95_is_the_95_percent_radius_of_a_circular_normal():
    # per-axis sigma s, RMS (2-D) r = sqrt(2) s, P(|e| < R) = 1 - exp(-R^2 / (2 s^2)) = 0.95
    r = 1.0
    s = r / math.sqrt(2)
    R = R95_PER_RMS * r
    assert 1 - math.exp(-R**2 / (2 * s**2)) == pytest.approx(0.95, abs=1e-12)


def _many_marks(doc, n=20):
    d = copy.deepcopy(doc)
    m0 = next(iter(d["marks"].values()))
    d["marks"] = {f"c{i:02d}": dict(m0) for i in range(n)}
    return d


def test_verdict_ready_only_when_the_plan_identifies_everything(doc):
    d = _many_marks(doc)
    for m in d["marks"].values():         # residuals at the noise: within the floor
        m["sigma_mm"], m["residual_mm"] = 0.005, [0.008, -0.004]
    d["identifiability"]["not_identifiable"] = []
    d["effects"] = []
    d.pop("verdict", None)
    d.pop("replication", None)     # the five marks' (not replicated), not these copies'
    d["validation_rms_mm"]["final_model"] = 0.012
    d["residual_rms_mm"]["final_model"] = 0.011
    v = judge(d)
    # the 95 % radius of a target's std: the calibration's part (6 / 34 of the residual's
    # variance), the default repeatability 0.01 mm, nothing unexplained
    assert v.target_std["unexplained_mm"] == 0.0
    assert v.target_std["total_mm"] == pytest.approx(math.sqrt(4e-5 * 6 / 34 + 0.01**2))
    assert v.status == "ready" and "0.025 mm (95 %)" in v.text
    d["identifiability"]["not_identifiable"] = [
        {"label": "joint_scale(joint 1)", "reason": "x", "fix": "add marks at q1 beyond +-60 deg"}]
    v = judge(d)
    assert v.status == "not reliable"
    assert "joint_scale(joint 1)" in v.text and "add marks at q1" in v.text
    d["identifiability"]["not_identifiable"] = []
    d["identifiability"]["rank"] = 5
    assert judge(d).status == "not reliable"
    d["identifiability"]["rank"] = 6
    d["validation_rms_mm"]["final_model"] = 0.05      # 4.5 x the fitted RMS
    assert judge(d).status == "check"
    d["validation_rms_mm"]["final_model"] = 0.012
    for m in d["marks"].values():         # marks without a measured noise: no floor known
        m.pop("sigma_mm")
    v = judge(d)
    assert v.status == "check" and "noise floor" in v.text


def test_the_report_reads_the_verdict_block_and_never_judges(doc):
    """The headline's verdict is calibration.json's block, sentence included, whatever
    the rest of the document says; a file without a block is not judged by the report."""
    d = copy.deepcopy(doc)
    d["verdict"] = {"status": "ready", "reasons": [], "text": "ready to use: as written"}
    d["identifiability"]["rank"] = 1        # judge() would say "not reliable"
    assert hl.verdict(d) == {"status": "ready", "text": "ready to use: as written",
                             "reasons": [], "residual_over_floor": None}
    assert hl.verdict({**d, "verdict": {"status": "check", "reasons": ["a", "b"]}})["text"] \
        == "check: a; b"
    d.pop("verdict")
    assert hl.verdict(d)["status"] == "check" and "no verdict" in hl.verdict(d)["text"]
    assert doc["verdict"]["text"] == Verdict.from_json(doc["verdict"]).text   # the owner's


def test_controller_offsets_make_the_nominal_model_true(doc):
    """Convention: the joint turns to q + c. With c added, the nominal zero z_nom gives
    the calibrated link angle: q + c + z_cal == q + z_nom."""
    a = hl.actions(doc)
    for o in a["controller_offsets"]:
        j = o["joint"] - 1
        zc, zn = doc["params"]["joint_zero_deg"][j], doc["nominal"]["joint_zero_deg"][j]
        assert o["add_to_offset_deg"] + zc == pytest.approx(zn)
    assert "counter-clockwise seen from above" in a["sign_convention"]
    assert any("vision-cal plan" in c["command"] for c in a["commands"])


def test_plot_titles_show_the_documented_rms(doc, monkeypatch):
    """One owner: the residual figure's titles print calibration.json's RMS, even when
    the marks alone would give another number (outliers, held-out marks)."""
    import matplotlib.axes

    titles = []
    orig = matplotlib.axes.Axes.set_title
    monkeypatch.setattr(matplotlib.axes.Axes, "set_title",
                        lambda self, t, *a, **k: (titles.append(t), orig(self, t, *a, **k))[1])
    d = copy.deepcopy(doc)
    d["residual_rms_mm"] = {"base_model": 0.1234, "final_model": 0.0567}
    plots.residual_field(d)
    assert any("fitted RMS 0.1234 mm" in t for t in titles)
    assert any("fitted RMS 0.0567 mm" in t for t in titles)


def test_mark_rows_flag_held_out_outliers_and_missing(doc):
    d = copy.deepcopy(doc)
    first = next(iter(d["marks"]))
    d["outliers"] = [first]
    d["missing_marks"] = ["v99"]
    rows = {r["id"]: r for r in hl.mark_rows(d, {"v99": "not in any usable photo"})}
    assert any("outlier" in f for f in rows[first]["flags"])
    assert rows["v99"]["flags"] == ["not measured: not in any usable photo"]
    assert rows[first]["residual_norm_mm"] == pytest.approx(
        math.hypot(*d["marks"][first]["residual_mm"]))


def test_joint_residuals_written_by_the_pipeline_explain_the_residuals(doc):
    """calibration.json's per-mark joint-angle residuals (what the report's joint figure
    draws, computed by the pipeline): turning the joints by them moves the pen by the
    mark's residual (to first order: the residuals are a few tenths of a degree)."""
    import numpy as np

    from vision_cal.model.kinematics import ScaraParams, forward

    p = ScaraParams.from_json(doc["params"])
    marks = doc["marks"]
    assert marks and all("residual_joint_deg" in m for m in marks.values())
    for m in marks.values():
        q = np.array([m["joints_deg"]], float)
        for key, res in (("residual_joint_deg", "residual_mm"),
                         ("residual_base_joint_deg", "residual_base_mm")):
            moved = forward(p, q + np.array([m[key]])) - forward(p, q)
            r = np.asarray(m[res])
            assert np.hypot(*(moved[0] - r)) < 0.02 * np.hypot(*r) + 1e-6


def test_an_older_calibration_json_is_reported_from_what_it_has(doc, tmp_path):
    """A calibration.json written before the report read only files (no ``dataset``, no
    joint-angle residuals, a verdict without its sentence): the report says what is not
    recorded and leaves out what it cannot draw, without recomputing anything."""
    from vision_cal.report.html import write_report

    d = copy.deepcopy(doc)
    d.pop("dataset")
    d["verdict"].pop("text")
    for m in d["marks"].values():
        m.pop("residual_joint_deg")
        m.pop("residual_base_joint_deg")
    (tmp_path / "calibration.json").write_text(json.dumps(d))
    page = write_report(tmp_path / "calibration.json").read_text()
    rep = json.loads((tmp_path / "report.json").read_text())
    assert "not recorded" in rep["dataset"] and rep["reference"] is None
    assert rep["headline"]["verdict"]["text"].startswith(d["verdict"]["status"] + ": ")
    assert "alt='joint residuals'" not in page and "alt='residual field'" in page


def test_the_sheet_height_figure_is_drawn_when_the_marks_have_a_grid_difference(doc):
    """A calibration whose marks were measured against the printed grid gets its sheet
    figure (it was drawn and thrown away: the report never showed it)."""
    d = copy.deepcopy(doc)
    assert plots.sheet_height(d) is None                  # nothing to draw
    for k, m in enumerate(d["marks"].values()):
        m["local_minus_global_mm"] = [0.001 * k, -0.002]
    png = plots.sheet_height(d)
    assert isinstance(png, bytes) and png.startswith(b"\x89PNG")


def test_the_console_says_one_reason_one_line_and_each_figure_by_its_own_name():
    """Issue 38: a pilot's "check before use" was one line of about 900 characters, and
    two different "noise floor" figures sat on consecutive lines: each reason is a line of
    its own (wrapped at the console's width), the controller's two ways each a line, the
    photos' noise named apart from the verdict's noise floor."""
    from vision_cal.report.summary import WIDTH, format_summary, verdict_lines

    reasons = ["not identified: joint_backlash(joint 1): " + "x " * 200, "the print's "
               "deviation from its layout is not measured: survey the sheet"]
    lines = verdict_lines({"status": "check", "reasons": reasons, "text": "check before use",
                           "expected_target_error_mm": 0.036})
    assert lines[0] == "check before use (expected target error 0.036 mm, 95 %): 2 reason(s)"
    assert all(len(ln) <= WIDTH for ln in lines), lines
    assert sum(ln.startswith("  - ") for ln in lines) == 2
    d = {"params": {"L1_mm": 344.0, "L2_mm": 260.0, "joint_zero_deg": [-2.6, -8.1],
                    "base_mm": [-420.0, -230.0]},
         "nominal": {"joint_zero_deg": [0.0, 0.0]}, "noise_floor_mm": 0.0163,
         "residual_rms_mm": {"base_model": 0.013, "final_model": 0.0128},
         "verdict": {"status": "check", "reasons": reasons, "text": "x", "floor_line":
                     "residual vs noise floor: 0.0128 mm vs 0.0176 mm (0.73x): within"}}
    text = format_summary(d)
    assert text.count("noise floor") == 1, text
    assert "  - keep the robot file's model and add to the controller's joint offsets: " \
           "joint 1: +2.6000 deg, joint 2: +8.1000 deg" in text.splitlines()
