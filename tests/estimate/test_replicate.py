"""Replication (issue 37): two halves' estimates against what each states
(``model/replication.compare``), and the robot fit replicated by two halves of its marks
(``estimate/replicate``) on kinematic worlds."""

import functools

import numpy as np
import pytest
from scipy import stats

from tests.conftest import SM5
from tests.plan.test_calibration_plan import NOMINAL, make_sheet
from vision_cal.estimate.replicate import candidate_splits, replicate
from vision_cal.estimate.verdict import judge
from vision_cal.model.lsq import Fit
from vision_cal.model.replication import compare
from vision_cal.model.robot import JointBacklash, RobotModel
from vision_cal.plan.calibration_plan import informative_plan
from vision_cal.world.truth_model import TrueRobot


def test_compare_is_the_chi_square_of_the_difference():
    # hand-computed: d = (1, 0) against diag(1, 1) + diag(1, 1): chi2 = 1 / 2 on 2 dof
    r = compare([1.0, 0.0], np.eye(2), [0.0, 0.0], np.eye(2))
    assert (r.chi2, r.dof, r.chi2_dof) == (0.5, 2, 0.25)
    assert r.p_value == pytest.approx(stats.chi2.sf(0.5, 2))
    # a direction neither half states (a shared gauge) is not a degree of freedom
    C = np.array([[1.0, 1.0], [1.0, 1.0]])
    r = compare([1.0, 1.0], C, [0.0, 0.0], C)
    assert r.dof == 1 and r.chi2 == pytest.approx(2.0 / 4.0)
    # parameters in mm and radians side by side: the rank is read on unit diagonal
    r = compare([1e-6, 1.0], np.diag([1e-12, 1.0]), [0.0, 0.0], np.diag([1e-12, 1.0]))
    assert r.dof == 2 and r.chi2 == pytest.approx(0.5 + 0.5)
    # the agreement rule is the floor's: p below alpha and chi2/dof beyond tol^2
    assert compare([10.0], [[1.0]], [0.0], [[1.0]]).agrees(1e-3, 1.25) is False
    assert compare([1.0], [[1.0]], [0.0], [[1.0]]).agrees(1e-3, 1.25) is True


@functools.lru_cache(maxsize=1)
def _plan():
    """The informative plan's 30 calibration marks (both elbows, balanced approaches)."""
    plan = [m for m in informative_plan(NOMINAL, make_sheet(), rng=3) if m.role == "calibration"]
    return np.array([m.joints_deg for m in plan]), np.array([m.approach for m in plan], float)


def _world(effects, seed, sig=0.005, rep=0.01):
    """The plan drawn by SM5 with ``effects``, measured with noise ``sig`` (the robot
    scattering by ``rep``), noise from ``seed``."""
    rng = np.random.default_rng(seed)
    q, s = (a.copy() for a in _plan())
    xy = TrueRobot.from_json(SM5.to_json(), effects).pen_mm(q, s) + rng.normal(
        0, np.hypot(sig, rep), q.shape)
    return q, s, xy, np.full(len(q), sig)


def _replicated(effects, model_effects, seed):
    q, s, xy, sig = _world(effects, seed)
    fit = Fit.from_estimate(q, xy, approach=s, model=RobotModel(SM5, model_effects),
                            sigma_mm=sig, robust=False)
    return replicate(fit.model, q, xy, s, sig, residual_scale=fit.residual_scale)


def test_the_halves_agree_on_a_right_model_and_read_a_wrong_one():
    """A hidden 0.3 % gear-ratio error of joint 1 left out of the model: the two elbows'
    fits disagree far beyond what each states (chi2/dof ~6 on kinematic worlds), where the
    model that has the robot's backlash agrees on the same plans (chi2/dof ~1)."""
    bl = [{"name": "joint_backlash", "joint": 2, "deg": 0.1}]
    scale = bl + [{"name": "joint_scale", "joint": 1, "scale": 0.003}]
    for seed in (3, 4):
        ok = _replicated(bl, (JointBacklash(2),), seed)
        assert ok["agree"] and ok["split"] == "elbow +1 | elbow -1", ok
        assert ok["params"]["dof"] == 7 and ok["params"]["chi2_dof"] < 3
        wrong = _replicated(scale, (JointBacklash(2),), seed)
        assert not wrong["agree"] and wrong["params"]["p"] < 1e-3, wrong
        assert "disagree" in wrong["text"]
        # the verdict is not ready with halves that disagree, and says why
        doc = {"marks": {}, "effects": [], "identifiability": {"n_params": 7},
               "validation_rms_mm": {"final_model": 0.01}, "replication": wrong}
        v = judge(doc)
        assert v.status == "check" and "two halves of the marks" in v.text


def test_a_split_that_cannot_identify_the_model_gives_way_to_the_next():
    """Joint 1 reached from one side only within an elbow: the backlash of joint 1 is not
    identifiable in that half, so the next split is used; too few marks: not replicated,
    said, and never ready."""
    q, s, xy, sig = _world([], 5)
    s[np.sin(np.radians(q[:, 1] + SM5.z2_deg)) > 0, 0] = 1.0
    model = RobotModel(SM5, (JointBacklash(1),))
    fit = Fit.from_estimate(q, xy, approach=s, model=model, sigma_mm=sig, robust=False)
    r = replicate(fit.model, q, xy, s, sig, residual_scale=fit.residual_scale)
    assert r["split"] != "elbow +1 | elbow -1" and r["agree"] is not None, r
    few = replicate(fit.model, q[:9], xy[:9], s[:9], sig[:9],
                    residual_scale=fit.residual_scale)
    assert few["agree"] is None and "parameters" in few["reason"]
    doc = {"marks": {}, "effects": [], "identifiability": {"n_params": 7},
           "validation_rms_mm": {"final_model": 0.01}, "replication": few}
    assert judge(doc).status == "check"
    assert judge(doc, stage="pilot").status == "ready"   # a pilot cannot be halved


def test_the_splits_are_disjoint_and_whole():
    q, s, _, _ = _world([], 6)
    for h in candidate_splits(q, s, SM5.z2_deg):
        assert not set(h.a) & set(h.b) and len(h.a) + len(h.b) == len(q), h.split
