"""vision_cal.model.solve: the one solver (a free-parameter mask, a robust loss, dense or
sparse Jacobians, a solve stopped on its limit is a failure) and the one covariance policy
(a direction the data do not fix is reported with an infinite std, never a small one)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import sparse

from vision_cal.errors import FailureUsed
from vision_cal.model.solve import covariance, solve


def _line(seed: int, n: int = 20, sigma: float = 0.1):
    rng = np.random.default_rng(seed)
    t = np.linspace(-1.0, 1.0, n)
    return t, 2.0 + 0.5 * t + rng.normal(0.0, sigma, n)


def _line_problem(t, y):
    A = np.column_stack([np.ones_like(t), t, t**2])
    return (lambda x: A @ x - y), (lambda x: A), A


def test_only_the_free_parameters_move_and_they_solve_the_reduced_problem():
    t, y = _line(1)
    res, jac, A = _line_problem(t, y)
    x0 = np.array([0.0, 0.0, 0.3])                      # the curvature held at 0.3
    sol = solve(res, x0, jac=jac, free=[True, True, False])
    assert sol and sol.x[2] == 0.3
    want, *_ = np.linalg.lstsq(A[:, :2], y - 0.3 * t**2, rcond=None)
    assert np.allclose(sol.x[:2], want, rtol=1e-10, atol=1e-12)
    assert sol.jacobian.shape == (len(t), 2) and sol.dof == len(t) - 2
    # the same with a sparse Jacobian (trust region, lsmr)
    sp = solve(res, x0, jac=lambda x: sparse.csr_matrix(A), free=[True, True, False],
               tr_solver="lsmr", xtol=1e-12, ftol=1e-12)
    assert sparse.issparse(sp.jacobian) and np.allclose(sp.x, sol.x, atol=1e-8)


def test_a_solve_stopped_on_its_limit_is_a_failure_with_its_reason():
    def rosen(x):
        return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0]])

    stopped = solve(rosen, [-1.2, 1.0], max_nfev=3)
    assert not stopped and "without converging" in stopped.reason
    assert stopped.last.x.shape == (2,)                  # where it stopped, on purpose
    with pytest.raises(FailureUsed):
        stopped.x
    done = solve(rosen, [-1.2, 1.0])
    assert done and np.allclose(done.x, [1.0, 1.0], atol=1e-8)


def test_the_stated_std_covers_the_scatter_of_the_estimates():
    """s^2 = SSR / dof: over 400 noisy lines the slope's estimates scatter as its stated
    std says (the ratio's sampling error is ~4 %: bounds at 15 %)."""
    est, std = [], []
    for seed in range(400):
        t, y = _line(seed, sigma=0.2)
        res, jac, _ = _line_problem(t, y)
        sol = solve(res, np.zeros(3), jac=jac)
        est.append(sol.x[1])
        std.append(sol.covariance(("a", "b", "c")).std[1])
    ratio = np.std(est) / np.sqrt(np.mean(np.square(std)))
    assert 0.85 < ratio < 1.15, ratio
    # at full rank the policy is s^2 (J^T J)^-1
    t, y = _line(5)
    res, jac, A = _line_problem(t, y)
    sol = solve(res, np.zeros(3), jac=jac)
    cov = sol.covariance()
    assert np.allclose(cov.matrix, sol.residual_variance * np.linalg.inv(A.T @ A), rtol=1e-10)
    assert cov.not_fixed == () and cov.rank == 3


def test_a_direction_the_data_do_not_fix_is_named_and_never_given_a_small_std():
    """Two offsets that only their sum moves: both have an infinite std (a pseudo-inverse
    would give each half the sum's), the sum's std is finite and right, their difference
    infinite; the slope is untouched."""
    t, y = _line(7)
    A = np.column_stack([np.ones_like(t), np.ones_like(t), t])
    cov = covariance(A, labels=("offset_a", "offset_b", "slope"), s2=0.01)
    assert cov.rank == 2 and len(cov.not_fixed) == 1
    assert set(cov.not_fixed[0].labels) == {"offset_a", "offset_b"}
    assert "offset_a" in cov.reason() and "slope" not in cov.reason()
    assert np.isinf(cov.std[:2]).all() and np.isfinite(cov.std[2])
    pinv_std = np.sqrt(np.diag(np.linalg.pinv(A.T @ A) * 0.01))
    assert np.all(pinv_std[:2] < 0.1)                      # what the policy refuses to say
    one = np.column_stack([np.ones_like(t), t])
    ref = np.sqrt(np.diag(np.linalg.inv(one.T @ one) * 0.01))
    s = cov.std_of([[1.0, 1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 0.0, 1.0]])
    assert np.isclose(s[0], ref[0], rtol=1e-9) and np.isinf(s[1])
    assert np.isclose(s[2], ref[1], rtol=1e-9) and np.isclose(cov.std[2], ref[1], rtol=1e-9)


def test_the_sandwich_with_white_noise_is_the_plain_covariance():
    t, _ = _line(3)
    A = np.column_stack([np.ones_like(t), t, t**2])
    sigma2 = 0.04
    plain = covariance(A, s2=sigma2)
    sandwich = covariance(A, meat=A.T @ (sigma2 * np.eye(len(t))) @ A)
    assert np.allclose(plain.matrix, sandwich.matrix, rtol=1e-10)


def test_a_robust_loss_keeps_an_outlier_from_pulling_the_fit():
    t, y = _line(11, sigma=0.01)
    y[3] += 5.0
    res, jac, _ = _line_problem(t, y)
    plain = solve(res, np.zeros(3), jac=jac)
    robust = solve(res, np.zeros(3), jac=jac, loss="soft_l1", f_scale=0.02)
    assert robust and abs(robust.x[1] - 0.5) < 0.02 < abs(plain.x[1] - 0.5)
    assert np.isclose(robust.cost, 0.5 * robust.residuals @ robust.residuals)
