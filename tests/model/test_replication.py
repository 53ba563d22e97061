"""Two halves' estimates compared against the covariance each states (model/replication)."""

import math

import numpy as np

from vision_cal.model.replication import compare


def _draws(rng, cov, truth):
    L = np.linalg.cholesky(cov)
    return truth + L @ rng.standard_normal(len(truth)), truth + L @ rng.standard_normal(len(truth))


def test_halves_drawn_as_stated_agree_and_a_stated_std_too_small_is_seen():
    """Halves drawn with their stated covariance give chi2/dof near 1 (within 4 sigma of
    the chi-square at 300 dof: sqrt(2 / 300) = 0.082 each); stating half the std reads 4."""
    rng = np.random.default_rng(11)
    n = 300
    A = rng.normal(size=(n, n)) / np.sqrt(n)
    cov = 0.01**2 * (A @ A.T + 0.5 * np.eye(n))
    truth = rng.normal(0, 0.2, n)
    a, b = _draws(rng, cov, truth)
    c = compare(a, cov, b, cov)
    assert c.n == n and c.dof == n
    assert abs(c.chi2_dof - 1.0) < 4 * math.sqrt(2.0 / n)
    assert c.p_value > 1e-4 and c.within(2.0) and c.agrees(1e-3, 1.3)
    assert c.correlation > 0.99               # both follow the same truth
    assert abs(c.rms_diff - math.sqrt(2 * np.trace(cov) / n)) < 0.15 * c.rms_diff
    small = compare(a, cov / 4, b, cov / 4)
    assert abs(small.chi2_dof - 4 * c.chi2_dof) < 1e-6 * small.chi2_dof
    assert not small.within(2.0) and small.p_value < 1e-6
    assert not small.agrees(1e-3, 1.3)


def test_a_gauge_is_left_out_of_the_degrees_of_freedom():
    """A covariance singular along a gauge (the mean removed from both halves) counts the
    rank; a difference along the gauge adds nothing; variances as a vector are a diagonal."""
    rng = np.random.default_rng(12)
    n = 50
    Q = np.eye(n) - np.ones((n, n)) / n
    cov = 0.02**2 * Q
    a, b = Q @ rng.normal(0, 0.02, n), Q @ rng.normal(0, 0.02, n)
    c = compare(a, cov, b, cov)
    assert c.dof == n - 1
    shifted = compare(a + 5.0, cov, b, cov)
    assert abs(shifted.chi2 - c.chi2) < 1e-6 * c.chi2
    d = compare(a, np.full(n, 0.02**2), b, 0.02**2)
    assert d.dof == n and abs(d.chi2 - np.sum((a - b) ** 2) / (2 * 0.02**2)) < 1e-9 * d.chi2
    assert set(c.to_json()) == {"dof", "chi2", "chi2_dof", "p"}   # calibration.json's
