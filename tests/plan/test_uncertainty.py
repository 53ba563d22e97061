"""Predicted std of a planned target against the misses of many recalibrations."""

import numpy as np

from tests.conftest import SM5, random_plan
from vision_cal.model.lsq import Fit
from vision_cal.model.kinematics import inverse
from vision_cal.model.robot import JointBacklash, RobotModel
from vision_cal.dataset.covariance import covariance_json, load_covariance
from vision_cal.plan.uncertainty import predicted_std_mm


def test_std_mm_matches_the_spread_of_real_misses():
    """Refit the same plan under fresh noise 300 times, plan a target with each fit and
    land it on the true robot: the per-axis RMS miss is the predicted std (to the
    sampling error of 300 draws, ~4 %, plus first-order error). Catches: the diagonal
    std used without correlations (L1, z and base are strongly correlated), the trace
    not halved, degrees and radians mixed in the file's covariance."""
    from vision_cal.world.truth_model import TrueRobot

    rng = np.random.default_rng(0)
    truth = TrueRobot.from_json(SM5.to_json(), [{"name": "joint_backlash", "joint": 2,
                                                 "deg": 0.1}])
    q, s = random_plan(12, rng)
    sigma = 0.05
    targets = np.array([[0.0, 0.0], [-150.0, 120.0]])
    misses, preds = [], []
    for k in range(300):
        xy = truth.pen_mm(q, s) + rng.normal(0, sigma, q.shape)
        fit = Fit.from_estimate(q, xy, approach=s, model=RobotModel(SM5, (JointBacklash(2),)),
                                robust=False)
        doc = {"covariance": covariance_json(fit.labels, fit.cov)}
        cov = load_covariance(doc, fit.model)
        phi = inverse(fit.params, targets, elbow=1)
        cmd = phi + np.degrees(0.5 * np.radians(fit.model.effects[0].deg)) * np.array([0, 1])
        assert np.allclose(fit.model.predict(cmd, np.ones((2, 2))), targets, atol=1e-6)
        misses.append(truth.pen_mm(cmd, np.ones((2, 2))) - targets)
        preds.append(predicted_std_mm(fit.model, cov, cmd, np.ones((2, 2))))
    misses, preds = np.array(misses), np.array(preds)
    rms_axis = np.sqrt(np.mean(misses**2, axis=(0, 2)))       # per target
    assert np.allclose(np.median(preds, axis=0), rms_axis, rtol=0.15), (preds.mean(0), rms_axis)


def test_covariance_round_trip_in_file_units():
    cov = np.diag([1.0, 4.0, np.radians(0.1) ** 2, np.radians(0.2) ** 2, 9.0, 16.0])
    labels = RobotModel(SM5).param_labels()
    doc = covariance_json(labels, cov)
    assert doc["params"][2] == "z1_deg" and np.isclose(doc["matrix"][2][2], 0.01)
    assert np.allclose(load_covariance({"covariance": doc}, RobotModel(SM5)), cov)
