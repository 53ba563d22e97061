import numpy as np
import pytest

from tests.conftest import SM5, random_plan
from vision_cal.calibrate.linear import linear_init
from vision_cal.calibrate.lsq import Fit
from vision_cal.errors import CalibrationError
from vision_cal.kinematics import forward
from vision_cal.model import JointBacklash, RobotModel


def test_linear_init_is_exact_on_clean_data():
    q, _ = random_plan(6, np.random.default_rng(0))
    p = linear_init(q, forward(SM5, q))
    np.testing.assert_allclose(p.vector, SM5.vector, atol=1e-9)


def test_recovers_truth_without_a_good_nominal_and_std_is_honest():
    z = []
    for seed in range(40):
        rng = np.random.default_rng(seed)
        q, _ = random_plan(20, rng)
        xy = forward(SM5, q) + rng.normal(0, 0.02, (20, 2))
        f = Fit.from_estimate(q, xy)
        assert abs(f.params.L1_mm - SM5.L1_mm) < 0.05
        assert abs(f.params.z1_deg - SM5.z1_deg) < 0.01
        z.append((f.params.vector - SM5.vector) / f.std)
    z = np.array(z)
    assert np.all((0.6 < z.std(axis=0)) & (z.std(axis=0) < 1.5)), z.std(axis=0)


def test_outlier_is_named_and_left_out():
    rng = np.random.default_rng(4)
    q, _ = random_plan(20, rng)
    xy = forward(SM5, q) + rng.normal(0, 0.01, (20, 2))
    xy[7] += [3.0, -2.0]
    f = Fit.from_estimate(q, xy, ids=[f"m{i}" for i in range(20)])
    assert not f.inliers[7] and f.inliers.sum() == 19
    assert "m7" in f.notes[0]
    assert abs(f.params.L2_mm - SM5.L2_mm) < 0.03


@pytest.mark.parametrize("q,words", [
    (np.array([[0, 0], [0, 30], [0, -30], [0, 60]], float), "joint 1 at 0 deg"),
    (np.array([[0, 10], [20, 10], [-20, 10], [40, 10]], float), "joint 2 at 10 deg"),
    (np.array([[0, 0], [20, 30]], float), "at least 3 marks"),
])
def test_degenerate_plans_are_refused(q, words):
    with pytest.raises(CalibrationError, match=words):
        Fit.from_estimate(q, forward(SM5, q))


def test_backlash_with_one_approach_is_not_identifiable():
    q, _ = random_plan(20, np.random.default_rng(2))
    model = RobotModel(SM5, (JointBacklash(joint=1),))
    with pytest.raises(CalibrationError, match=r"z1 ~ joint_backlash\(joint 1\)"):
        Fit.from_estimate(q, forward(SM5, q), approach=np.ones_like(q), model=model)
