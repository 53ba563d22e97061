"""The print's correlated part (issue 28 follow-up): an error every mark shares through its
photo's mapping (the as-printed layout's uncertainty: a shear, a stretch of the sheet) is
taken up by the parameters and leaves no residual, so the fit's own covariance (scaled by
the residual) cannot show it; ``Fit.with_shared_error`` adds it."""

import numpy as np
from scipy import stats

from tests.conftest import SM5, random_plan
from vision_cal.measure.asprinted import field_basis
from vision_cal.measure.print_stage import print_field_cov
from vision_cal.model.kinematics import forward
from vision_cal.model.lsq import Fit

N_SEEDS = 300
N_MARKS = 30
NOISE_MM = 0.004          # each mark's own noise, per axis
#: the layout's field: its linear part (stretch, shear, turn) 0.01 mm at the sheet's edge,
#: a little perspective; shift and scale are the gauge's (0)
FIELD = {"basis": "homography", "centre_mm": [0.0, 0.0], "scale_mm": 297.0,
         "cov_mm2": np.diag([0, 0, 1e-4, 1e-4, 1e-4, 1e-4, 2e-5, 2e-5]).tolist()}


def _z(shared: bool) -> np.ndarray:
    """(seeds, 6) (found - truth) / std of the six base parameters."""
    out = []
    C8 = np.asarray(FIELD["cov_mm2"])
    for seed in range(N_SEEDS):
        rng = np.random.default_rng(seed)
        q, _ = random_plan(N_MARKS, rng)
        xy0 = forward(SM5, q)
        c = rng.multivariate_normal(np.zeros(8), C8)
        B = field_basis(xy0, FIELD["centre_mm"], FIELD["scale_mm"])
        xy = xy0 + (B @ c).reshape(-1, 2) + rng.normal(0, NOISE_MM, xy0.shape)
        sig = np.full(N_MARKS, NOISE_MM)
        f = Fit.from_estimate(q, xy, sigma_mm=sig, robust=False)
        if shared:
            f = f.with_shared_error(q, None, print_field_cov({"field": FIELD}, xy), sig)
        out.append((f.model.vector[:6] - SM5.vector) / f.std[:6])
    return np.array(out)


def test_the_shared_error_is_in_the_parameters_std():
    """mean(z^2) per parameter within the chi-square window (1e-4 two-sided, Bonferroni
    over 6) with the shared part added; without it (the independent treatment: the
    residual's scale alone) some parameter is far beyond it."""
    lo, hi = (stats.chi2.ppf(p, N_SEEDS) / N_SEEDS for p in (1e-4 / 12, 1 - 1e-4 / 12))
    # the fit's own std is estimated from 2N - 6 dof: z is Student's, mean z^2 up to
    # dof / (dof - 2) (the window widened by it)
    dof = 2 * N_MARKS - 6
    hi *= dof / (dof - 2)
    old = np.mean(_z(False) ** 2, axis=0)
    new = np.mean(_z(True) ** 2, axis=0)
    assert old.max() > hi, old           # the independent treatment understates
    assert np.all(new < hi), new
    # and not by far on the safe side: what the shared part adds is what it does
    assert np.all(new > 0.5 * lo), new
