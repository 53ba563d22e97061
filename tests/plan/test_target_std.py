"""A planned target's std_mm is the 1-sigma of where it lands (issue 37): the calibration's
covariance, the repeatability, what the model leaves, the print, the paper's scale off the
paper; and the paper's scale is a stated uncertainty of every length."""

import functools
import json

import numpy as np
import pytest

from tests.conftest import SM5
from tests.plan.test_calibration_plan import NOMINAL, make_sheet
from vision_cal.estimate.paper_scale import check_bars, paper_scale_block
from vision_cal.commands.main import main
from vision_cal.dataset.calibration import load_calibration
from vision_cal.dataset.covariance import load_covariance
from vision_cal.errors import VisionCalError
from vision_cal.model.lsq import Fit
from vision_cal.model.robot import JointBacklash, RobotModel
from vision_cal.plan.calibration_plan import informative_plan
from vision_cal.plan.compensate import plan_targets
from vision_cal.plan.uncertainty import target_std
from vision_cal.world.truth_model import TrueRobot
from vision_cal.actions.pipeline import calibrate_dataset

BACKLASH = [{"name": "joint_backlash", "joint": 2, "deg": 0.1}]
REP, SIG = 0.012, 0.005


@functools.lru_cache(maxsize=1)
def _plan():
    return informative_plan(NOMINAL, make_sheet(), rng=4, n_repeats=8)


def _session(tmp_path, seed, *, sheet=None, scale=1.0):
    """The informative plan with 8 repeats drawn by SM5 with a 0.1 deg backlash (the robot
    scatters by REP), marks measured to SIG on a paper whose scale is ``scale``."""
    rng = np.random.default_rng(seed)
    plan = _plan()
    q = np.array([m.joints_deg for m in plan])
    s = np.array([m.approach for m in plan], float)
    truth = TrueRobot.from_json(SM5.to_json(), BACKLASH)
    xy = scale * (truth.pen_mm(q, s) + rng.normal(0, REP, q.shape)) + rng.normal(0, SIG, q.shape)
    raw = {"format": "vision-cal/1", "robot": NOMINAL.to_json(),
           "marks": [dict(m.to_json(), measured_mm=p.tolist(), measured_sigma_mm=SIG)
                     for m, p in zip(plan, xy)]}
    if sheet is not None:
        raw["sheet"] = sheet.to_json()
    (tmp_path / "session.json").write_text(json.dumps(raw))
    return truth


def test_std_mm_covers_where_the_targets_land(tmp_path):
    """One calibration of a kinematic world (the pipeline as a user runs it), 100 targets
    planned with it on both elbows (those within the limits) and landed on the true robot with its 0.012 mm
    repeatability: the misses fall inside the stated 95 % radius (2.448 std_mm) at about
    that rate (binomial std 1.5 %, and the calibration's error shared by every target) and
    their RMS is the stated std within 30 %. The calibration's covariance alone (the old
    std_mm, 0.003-0.005 mm) held about a fifth of them."""
    truth = _session(tmp_path, 8)
    calibrate_dataset(tmp_path, out_dir=tmp_path / "out")
    model, doc = load_calibration(tmp_path / "out" / "calibration.json")
    cov = load_covariance(doc, model)
    rng = np.random.default_rng(1)
    x0, y0, x1, y1 = make_sheet().extent_mm
    xy = np.column_stack([rng.uniform(x0 + 20, x1 - 20, 100), rng.uniform(y0 + 20, y1 - 20, 100)])
    miss, std, cal = [], [], []
    for elbow in (1, -1):
        ok = [p for p in plan_targets(model, list(range(100)), xy, elbow=elbow) if p.status == "ok"]
        q, a = np.array([p.q_deg for p in ok]), np.array([p.approach for p in ok], float)
        t = np.array([p.target_mm for p in ok])
        ts = target_std(model, cov, q, a, t, doc)
        assert np.all(ts.repeatability_mm == doc["verdict"]["repeatability_mm"])
        miss.append(truth.pen_mm(q, a) + rng.normal(0, REP, q.shape) - t)
        std.append(ts.total_mm)
        cal.append(ts.calibration_mm)
    miss, std, cal = np.concatenate(miss), np.concatenate(std), np.concatenate(cal)
    err = np.hypot(*miss.T)
    assert len(err) > 80      # both elbows, within the joint limits
    assert 0.88 < np.mean(err < 2.448 * std) <= 1.0, np.mean(err < 2.448 * std)
    assert 0.7 < np.sqrt(np.mean(miss**2)) / np.sqrt(np.mean(std**2)) < 1.3
    assert np.mean(err < 2.448 * cal) < 0.6          # the covariance alone does not cover
    # the verdict's expected error is the same statement at the 95 % radius
    assert 0.88 < np.mean(err < doc["verdict"]["expected_target_error_mm"])


def test_the_papers_scale_is_in_every_lengths_stated_std(tmp_path):
    """A paper that shrank 0.15 %: the marks (in the paper's mm) give L1 and L2 0.5 and
    0.4 mm long with stds of a few micrometres (100 std); the stated std with the paper's
    scale (a 0.2 % prior) holds them, and a target 100 mm off the paper carries 0.2 mm.
    The printed bars measured with a caliper narrow it to the reading's 0.035 %."""
    sheet = make_sheet()
    _session(tmp_path, 9, sheet=sheet, scale=1.0015)
    doc = calibrate_dataset(tmp_path, out_dir=tmp_path / "out").document
    ps, p, s = doc["paper_scale"], doc["params"], doc["std"]
    assert ps["source"] == "prior" and ps["scale_std"] == 0.002
    for k in ("L1_mm", "L2_mm"):
        err = p[k] - getattr(SM5, k)
        assert abs(err) > 20 * s[k]                            # the marks cannot see it
        assert abs(err) < 3 * ps["std_with_paper_scale"][k]   # the stated std holds it
        assert ps["std_with_paper_scale"][k] == pytest.approx(
            np.hypot(s[k], 0.002 * p[k]))
    assert "--bars-mm" in ps["reason"]
    model, _ = load_calibration(tmp_path / "out" / "calibration.json")
    x0, y0, x1, y1 = sheet.extent_mm
    t = np.array([[x0 + 100.0, y0 + 100.0], [0.0, y0 - 100.0]])  # on, 100 mm off
    q = np.array([p.q_deg for p in plan_targets(model, ["on", "off"], t)])
    ts = target_std(model, load_covariance(doc, model), q, np.ones((2, 2)), t, doc)
    assert ts.paper_scale_mm[0] == 0.0
    assert ts.paper_scale_mm[1] == pytest.approx(0.002 * 100 / np.sqrt(2))
    # the bars as measured on the shrunk paper (100 / 1.0015 mm): lengths in physical mm,
    # the scale known to the caliper's reading
    bar = round(100 / 1.0015, 2)
    doc = calibrate_dataset(tmp_path, out_dir=tmp_path / "out2", bars_mm=(bar, bar)).document
    ps = doc["paper_scale"]
    assert ps["source"] == "measured bars" and ps["scale_std"] == pytest.approx(
        0.05 / 100 / np.sqrt(2))
    phys = doc["printer_scale"]["physical_mm"]
    assert doc["printer_scale"]["source"] == "--bars-mm"
    for k in ("L1_mm", "L2_mm"):   # the physical lengths within the narrower std
        assert abs(phys[k] - getattr(SM5, k)) < 3 * ps["std_with_paper_scale"][k]
        assert ps["std_with_paper_scale"][k] < 0.3 * np.hypot(s[k], 0.002 * p[k])


def test_bars_that_cannot_be_a_100_mm_bar_are_refused(tmp_path, capsys):
    assert check_bars((100.2, 99.9)) == (100.2, 99.9)
    with pytest.raises(VisionCalError, match="measure it again") as e:
        check_bars((110.0, 100.0))
    assert e.value.field == "--bars-mm"
    (tmp_path / "data").mkdir()
    _session(tmp_path / "data", 3, sheet=make_sheet())
    assert main(["calibrate", str(tmp_path / "data"), "--out", str(tmp_path / "o"),
                 "--bars-mm", "110", "100", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--bars-mm" in err[0], err
    assert not (tmp_path / "o" / "calibration.json").exists()
    # without a sheet (an instrument in physical mm) there is no paper to scale
    assert paper_scale_block(None, {"L1_mm": 1.0}, {"L1_mm": 0.1}, None) is None


def test_an_old_calibration_gives_its_covariance_and_repeatability():
    """A calibration.json written before the parts: std_mm from the covariance and the
    verdict's repeatability (a file without either: the covariance alone)."""
    rng = np.random.default_rng(2)
    plan = _plan()
    q = np.array([m.joints_deg for m in plan])
    s = np.array([m.approach for m in plan], float)
    xy = TrueRobot.from_json(SM5.to_json(), BACKLASH).pen_mm(q, s) + rng.normal(0, 0.01, q.shape)
    fit = Fit.from_estimate(q, xy, approach=s, model=RobotModel(SM5, (JointBacklash(2),)))
    t = xy[:3]
    ts = target_std(fit.model, fit.cov, q[:3], s[:3], t, {"verdict": {"repeatability_mm": 0.01}})
    assert np.allclose(ts.total_mm, np.hypot(ts.calibration_mm, 0.01))
    assert np.allclose(target_std(fit.model, fit.cov, q[:3], s[:3], t, {}).total_mm,
                       ts.calibration_mm)
