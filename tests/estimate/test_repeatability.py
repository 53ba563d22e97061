"""The robot's repeatability from marks drawn twice (issue 37): an unbiased estimate with its
own std, never 0 for want of evidence, a stated prior when the pairs cannot resolve it."""

import numpy as np
import pytest

from tests.estimate.test_verdict import _fit_doc
from vision_cal.estimate.verdict import judge, repeatability_from_repeats


def _pairs(rng, n_pairs, r_true, sig_true, sig_stated):
    """``n_pairs`` marks drawn twice at the same command: each measured with noise
    ``sig_true`` per axis, stated as ``sig_stated``; the robot scatters by ``r_true``."""
    marks = {}
    for i in range(n_pairs):
        for k in range(2):
            marks[f"m{i}_{k}"] = {"joints_deg": [float(i), 10.0], "approach": [1, -1],
                                  "sigma_mm": sig_stated, "measured_mm": rng.normal(
                                      0, np.hypot(r_true, sig_true), 2).tolist()}
    return marks


def test_the_pairs_estimate_is_unbiased_and_states_its_own_std():
    """300 designs of 8 pairs, a robot of 0.006 mm under a 0.008 mm measurer: the mean of
    the r^2 estimates is r^2 within 4 of its std over 300 (a clip at 0 or a square root
    taken before averaging would move it), and the std each states is the scatter of the
    estimates (to the sampling error of 300 draws, ~5 %, and of the std's own estimate)."""
    rng = np.random.default_rng(3)
    r_true, sig = 0.006, 0.008
    est = [repeatability_from_repeats(_pairs(rng, 8, r_true, sig, sig)) for _ in range(300)]
    r2 = np.array([e.r2_mm2 for e in est])
    sd = np.array([e.r2_std_mm2 for e in est])
    assert abs(r2.mean() - r_true**2) < 4 * r2.std() / np.sqrt(len(r2)), (r2.mean(), r_true**2)
    assert np.sqrt(np.mean(sd**2)) == pytest.approx(r2.std(), rel=0.25)
    assert all(e.mm > 0 for e in est)       # never 0, whatever the pairs said
    assert any(e.r2_mm2 < 0 for e in est)   # the unbiased estimate can be negative


def test_a_measurer_that_overstates_its_noise_does_not_read_the_robot_as_zero():
    """The README's rehearsal: marks stated to 0.0104 mm that are right to 0.0070 mm, a
    robot of 0.01 mm, 8 pairs: the pairs cannot resolve it from the stated noise (a clip
    at 0 read 0.0 mm): the default 0.01 mm is used and said; a robot block's larger figure
    is kept (never the pairs' upper bound, whose std comes from 8 terms)."""
    rng = np.random.default_rng(11)
    zeros = 0
    for _ in range(50):
        marks = _pairs(rng, 8, 0.01, 0.0070, 0.0104)
        rp = repeatability_from_repeats(marks)
        assert rp.mm > 0.005, rp
        zeros += rp.r2_mm2 < 0
        if not rp.measured:   # the prior, or the pairs' estimate where it is above it
            assert "not resolved" in rp.why and rp.mm >= 0.01
            assert (rp.mm, rp.source) == (0.01, "default") or rp.mm**2 == pytest.approx(
                rp.r2_mm2)
        big = repeatability_from_repeats(marks, prior_mm=0.02)
        if not big.measured and big.r2_mm2 < 0.02**2:
            assert (big.mm, big.source) == (0.02, "robot block") and "at most" in big.why
    assert zeros >= 5    # the case that read 0.0 mm happens often


def test_too_few_pairs_fall_back_to_the_stated_prior():
    rng = np.random.default_rng(5)
    rp = repeatability_from_repeats(_pairs(rng, 2, 0.02, 0.005, 0.005))
    assert (rp.mm, rp.source, rp.n_pairs, rp.measured) == (0.01, "default", 2, False)
    assert "verdict.default_repeatability_mm" in rp.why and "2 pair(s)" in rp.why
    rp = repeatability_from_repeats({}, prior_mm=0.015)
    assert (rp.mm, rp.source) == (0.015, "robot block") and "robot block" in rp.why
    assert repeatability_from_repeats({}, prior_mm=0.0).mm == 0.01   # never 0
    # the verdict says where its figure came from, and carries the pairs' numbers
    v = judge(_fit_doc(seed=2))
    assert v.repeatability_mm == 0.01 and v.repeatability_source == "default"
    assert v.repeatability["n_pairs"] == 0 and "0 pair(s)" in v.repeatability["why"]


def test_a_floor_eight_pairs_measured_is_not_a_known_floor():
    """8 pairs know the floor's variance within about 35 %: a residual 1.5 times a floor
    they measured (variance 2.3 times, 70 dof) is what a floor read low by chance gives
    (the kinematic bench's robots of 0.0125 mm read as 0.0076 mm: "the model misses
    something" with nothing missing), so the F test of the two is not beyond the gate;
    against a floor taken as known (a prior) it is."""
    from vision_cal.estimate.verdict import floor_test

    res = np.tile([[0.015, 0.0]], (36, 1)) * np.sqrt(2.0)    # chi2 = 72 x 2.25 on 70 dof
    known = floor_test(res, np.zeros(36), 0.01, n_params=2)
    measured = floor_test(res, np.zeros(36), 0.01, n_params=2, floor_dof=16)
    assert known.ratio == measured.ratio == pytest.approx(1.5 * np.sqrt(72 / 70))
    assert known.beyond and not measured.beyond
    assert 1e-3 < measured.p_value < 0.1
    # a residual far beyond a floor the pairs measured still is
    assert floor_test(2 * res, np.zeros(36), 0.01, n_params=2, floor_dof=16).beyond
    rp = repeatability_from_repeats(_pairs(np.random.default_rng(1), 8, 0.02, 0.004, 0.004))
    assert rp.measured and rp.floor_dof == 16
    assert repeatability_from_repeats({}).floor_dof is None
