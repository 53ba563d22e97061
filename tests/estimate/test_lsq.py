import re
from dataclasses import replace

import numpy as np
import pytest

from tests.conftest import SM5, random_plan
from vision_cal.model.linear import linear_init
from vision_cal.model.lsq import Fit
from vision_cal.config import DEFAULT, FitConfig
from vision_cal.errors import CalibrationError
from vision_cal.model.kinematics import forward
from vision_cal.model.robot import JointBacklash, RobotModel


def test_linear_init_is_exact_on_clean_data():
    q, _ = random_plan(6, np.random.default_rng(0))
    p = linear_init(q, forward(SM5, q))
    np.testing.assert_allclose(p.vector, SM5.vector, atol=1e-9)


#: seeds for the covariance check: enough that a std 20 % off in either direction falls
#: outside the chi-square window (checked in the test itself)
N_SEEDS = 800


def test_recovers_truth_without_a_good_nominal_and_std_is_honest():
    """z = (found - truth) / std over many seeds: with 20 marks (40 residuals, 6 params)
    the std is itself estimated from 34 dof, so z follows Student's t with 34 dof and
    mean(z^2) ~ 34/32 chi2(n)/n. The window is its 1e-4 two-sided quantiles per parameter
    (Bonferroni over 6): a std wrong by 20 % (z^2 scaled by 1/0.8^2 or 1/1.2^2) lands
    outside it."""
    from scipy import stats

    z = []
    for seed in range(N_SEEDS):
        rng = np.random.default_rng(seed)
        q, _ = random_plan(20, rng)
        xy = forward(SM5, q) + rng.normal(0, 0.02, (20, 2))
        f = Fit.from_estimate(q, xy)
        err = f.params.vector - SM5.vector
        assert np.all(np.abs(err) < 6 * f.std), (seed, err / f.std)    # no wild fit
        z.append(err / f.std)
    z = np.array(z)
    dof = 2 * 20 - 6
    t_var = dof / (dof - 2)
    a = 1e-4 / 6
    lo = t_var * stats.chi2.ppf(a / 2, N_SEEDS) / N_SEEDS
    hi = t_var * stats.chi2.ppf(1 - a / 2, N_SEEDS) / N_SEEDS
    # power: a std 20 % too large or too small is outside the window
    assert t_var / 1.2**2 < lo and hi < t_var / 0.8**2
    ms = np.mean(z**2, axis=0)
    assert np.all((lo < ms) & (ms < hi)), (ms, lo, hi)
    # and unbiased: the mean z within 4 of its standard errors
    assert np.all(np.abs(z.mean(axis=0)) < 4 * np.sqrt(t_var / N_SEEDS)), z.mean(axis=0)


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
    """A fit that cannot be made is a falsy value with the reason (callers branch on it);
    ``or_raise`` ends the run with that reason."""
    f = Fit.from_estimate(q, forward(SM5, q))
    assert not f and re.search(words, f.reason)
    with pytest.raises(CalibrationError, match=words):
        f.or_raise()


def test_backlash_with_one_approach_is_not_identifiable():
    q, _ = random_plan(20, np.random.default_rng(2))
    model = RobotModel(SM5, (JointBacklash(joint=1),))
    f = Fit.from_estimate(q, forward(SM5, q), approach=np.ones_like(q), model=model)
    assert not f and re.search(r"z1 ~ joint_backlash\(joint 1\)", f.reason)


def test_the_condition_number_limit_is_read_from_the_config_passed_in():
    """A limit below the plan's conditioning makes the same fit unidentifiable."""
    q, _ = random_plan(20, np.random.default_rng(2))
    f = Fit.from_estimate(q, forward(SM5, q))
    assert f and f.cond > 2
    tight = replace(DEFAULT, fit=FitConfig(condition_number_limit=f.cond / 2))
    assert not Fit.from_estimate(q, forward(SM5, q), config=tight)
