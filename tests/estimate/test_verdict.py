"""The noise-floor gate and the verdict block (kinematic data: the gate reads only the
residuals and the per-mark noise, so no photograph is needed)."""

import numpy as np
import pytest
from scipy import stats

from tests.conftest import SM5, random_plan
from vision_cal.model.lsq import Fit
from vision_cal.estimate.verdict import (Verdict, floor_test, judge, judge_camera_poses,
                                        repeatability_from_repeats)
from vision_cal.world.truth_model import TrueRobot

SIGMA = 0.006   # measurer's per-axis std
REP = 0.01      # robot repeatability, per axis


def _fit_doc(effects=(), seed=0, n=40):
    """A calibration document of the base model fitted to a world with ``effects``."""
    rng = np.random.default_rng(seed)
    q, s = random_plan(n, rng)
    truth = TrueRobot.from_json(SM5.to_json(), effects)
    xy = truth.pen_mm(q, s) + rng.normal(0, np.hypot(SIGMA, REP), (n, 2))
    fit = Fit.from_estimate(q, xy, approach=s, sigma_mm=np.full(n, SIGMA), robust=False)
    marks = {f"c{i:02d}": {"residual_mm": fit.residuals_mm[i].tolist(), "sigma_mm": SIGMA,
                           "role": "calibration"} for i in range(n)}
    return {"marks": marks, "identifiability": {"rank": 6, "n_params": 6,
                                                "not_identifiable": []},
            "effects": [], "residual_rms_mm": {"final_model": fit.rms_mm},
            "validation_rms_mm": {"final_model": 1.1 * fit.rms_mm}}


def test_floor_is_a_chi_square_of_the_declared_noise():
    # hand-computed: two marks, residuals (0.03, 0.04) and (0, 0), noise 0.03 + 0.04 -> var
    # 0.0025 per axis: chi2 = 0.0025 / 0.0025 = 1 on 4 - 1 dof
    f = floor_test([[0.03, 0.04], [0.0, 0.0]], [0.03, 0.03], 0.04, n_params=1)
    assert f.chi2 == pytest.approx(1.0) and f.dof == 3
    assert f.p_value == pytest.approx(stats.chi2.sf(1.0, 3))
    assert f.ratio == pytest.approx(np.sqrt(1 / 3))


def test_clean_fit_is_within_the_floor_and_ready():
    for seed in range(5):
        v = judge(_fit_doc(seed=seed), repeatability_mm=REP)
        # ratio of an honest fit: sqrt(chi2_dof / dof), 74 dof -> within 1 +- 0.4 at 1e-4
        assert abs(v.residual_over_floor - 1) < 0.4, v
        assert v.status == "ready", v.reasons


def test_missing_effect_is_beyond_the_floor_and_never_ready():
    # a coupling the base model cannot absorb: joint 2 turns 0.001 deg per degree of q1
    # (not a library effect): residuals of ~0.1 mm against a 0.016 mm floor
    eff = [{"name": "joint_terms", "joint": 2, "terms": [{"feature": "q1*q2", "coef": 2e-5}]}]
    v = judge(_fit_doc(eff, seed=11), repeatability_mm=REP)
    assert v.floor["beyond"] and v.residual_over_floor > 2
    assert v.status == "not reliable"
    assert "times the noise floor" in v.text and "chi2" in v.floor_line
    # the same residual with a floor declared 10x larger is within it
    v = judge(_fit_doc(eff, seed=11), repeatability_mm=0.2)
    assert not v.floor["beyond"]


def test_drift_and_structure_downgrade_and_the_block_round_trips():
    d = _fit_doc(seed=3)
    d["effects"] = [{"name": "drift", "size_mm": 0.05, "along": "joint 1 zero"}]
    v = judge(d, repeatability_mm=REP)
    assert v.status == "not reliable" and "warm it up" in v.text
    d["effects"] = [{"name": "unexplained", "seen": ["joint2 residual has a harmonic 3"]}]
    v = judge(d, repeatability_mm=REP)
    assert v.status == "check" and "harmonic 3" in v.text
    d["effects"] = []
    d["outliers"] = ["c03"]
    assert judge(d, repeatability_mm=REP).status == "check"
    back = Verdict.from_json(v.to_json())
    assert back.to_json() == v.to_json() and back.text == v.text
    assert set(v.to_json()) >= {"status", "expected_target_error_mm", "residual_over_floor",
                                "reasons"}


def test_repeatability_measured_from_marks_drawn_twice():
    rng = np.random.default_rng(21)
    r_true, sig, n = 0.02, 0.004, 400      # many pairs: the estimate's std ~ r / sqrt(n)
    marks = {}
    for i in range(n):
        q = [float(i), 0.0]
        for k in range(2):
            marks[f"m{i}_{k}"] = {"joints_deg": q, "approach": [1, 1], "sigma_mm": sig,
                                  "measured_mm": (rng.normal(0, np.hypot(r_true, sig), 2)
                                                  ).tolist()}
    rp = repeatability_from_repeats(marks)
    assert rp.n_pairs == n and rp.measured and rp.source == f"{n} pairs of marks drawn at " \
        "the same command"
    # std of r: (r^2 + sig^2) / (2 r sqrt(n)) = 0.52 um here, and the one it states
    assert abs(rp.mm - r_true) < 4 * rp.std_mm
    assert rp.std_mm == pytest.approx((r_true**2 + sig**2) / (2 * r_true * np.sqrt(n)), rel=0.2)
    few = repeatability_from_repeats(dict(list(marks.items())[:6]))   # 3 pairs: the default
    assert not few.measured and few.source == "default" and few.mm == 0.01
    assert "3 pair(s)" in few.why and "4 needed" in few.why


def test_one_target_far_off_is_read_though_the_rms_hides_it():
    # 200 fitted marks, one 0.09 mm off (7.7 times its 2-D noise RMS of 0.0117 mm): the
    # chi-square of all of them moves by ~60 on ~394 dof (ratio ~1.07, within the floor)
    d = _fit_doc(seed=5, n=200)
    d["validation_rms_mm"] = {"final_model": d["residual_rms_mm"]["final_model"]}
    v = judge(d, repeatability_mm=REP)
    assert v.status == "ready", v.reasons
    assert v.max_target_error["of"] == "fitted" and not v.max_target_error["beyond"]
    r = np.asarray(d["marks"]["c17"]["residual_mm"])
    d["marks"]["c17"]["residual_mm"] = (r / np.hypot(*r) * 0.09).tolist()
    v = judge(d, repeatability_mm=REP)
    assert not v.floor["beyond"]
    assert v.status == "check" and "c17" in v.text and "largest" in v.text
    m = v.max_target_error
    assert m["mark"] == "c17" and m["error_mm"] == pytest.approx(0.09) and m["beyond"]
    assert Verdict.from_json(v.to_json()).max_target_error == m
    # held-out marks, when there are, are the targets judged
    d["marks"]["c17"]["role"] = "validation"
    assert judge(d, repeatability_mm=REP).max_target_error["of"] == "held-out"


def test_the_arm_camera_verdict_reads_one_photo_far_off():
    """The arm camera's verdict reads the largest held-out error as the marks' does: 200
    photos, one whose leave-one-out flange error is 0.09 mm (7.7 times its 2-D noise RMS):
    the held-out floor moves by ~60 on ~400 dof (within it), the largest error is a reason."""
    rng = np.random.default_rng(7)
    n, p = 200, 12
    sd = np.hypot(SIGMA, REP)
    res = rng.normal(0, sd, (n, 2)) * np.sqrt(1 - p / (2 * n))
    held = res / (1 - p / (2 * n))
    names = [f"pose_{i:03d}.png" for i in range(n)]
    v = judge_camera_poses(res, np.full(n, SIGMA), held, n_params=p, repeatability_mm=REP,
                           ids=names)
    assert v.status == "ready", v.reasons
    assert v.max_target_error["of"] == "held-out" and not v.max_target_error["beyond"]
    held[17] *= 0.09 / np.hypot(*held[17])
    v = judge_camera_poses(res, np.full(n, SIGMA), held, n_params=p, repeatability_mm=REP,
                           ids=names)
    assert not v.heldout_floor["beyond"] and not v.floor["beyond"]
    assert v.status == "check" and "pose_017.png" in v.text and "largest" in v.text
    assert v.max_target_error["mark"] == "pose_017.png" and v.max_target_error["beyond"]


def test_moved_photos_and_a_lens_read_as_height_are_read():
    d = _fit_doc(seed=6)
    assert judge(d, repeatability_mm=REP).status == "ready"
    d["diagnosis"] = {"per_photo_offsets": [{"file": "img_004.png", "flagged": True},
                                            {"file": "img_005.png", "flagged": False}]}
    v = judge(d, repeatability_mm=REP)
    assert v.status == "check" and "img_004.png" in v.text and "img_005.png" not in v.text
    d["diagnosis"] = {"sheet_height": {"claimed": False, "max_abs_mark_height_mm": 0.099,
                                       "not_claimed": "... what a slightly wrong lens leaves",
                                       "not_claimed_as": "lens"}}
    d["marks"]["c04"]["local_minus_global_mm"] = [0.03, -0.04]
    v = judge(d, repeatability_mm=REP)
    assert v.status == "check" and "by up to 0.050 mm" in v.text


def test_unreliable_marks_are_read():
    d = _fit_doc(seed=7)
    d["marks"]["c02"]["status"] = "unreliable"
    v = judge(d, repeatability_mm=REP)
    assert v.status == "check" and "c02" in v.text


def test_scans_not_run_are_said():
    d = _fit_doc(seed=8)
    d["diagnosis"] = {"discovery": {"skipped": "the scans did not run: the sheet is not flat"}}
    v = judge(d, repeatability_mm=REP)
    assert v.status == "check" and "sheet is not flat" in v.text
