"""Replication: the same quantity from two independent halves of the data, against what each
half states (issue 37, "Numbers that hold"; mrcal's cross-validation diff is the idea).

:func:`compare` takes two estimates ``a``, ``b`` (any shape, flattened to n values in the
same order) of one quantity and the covariance each states, ``cov_a``, ``cov_b`` ((n, n), or
(n,) variances, or one variance for all). The halves share no data, so if each covariance
is right their difference ``d = a - b`` has covariance ``C = cov_a + cov_b`` and

    chi2 = d' C^+ d        is chi-square with  dof = rank(C)

degrees of freedom (``C^+`` the pseudo-inverse on the directions ``C`` states: a gauge the
halves share, such as a layout's similarity removed from both, or positions that only
``P < n`` parameters move, leave ``C`` singular). The rank is read on ``C`` scaled to unit
diagonal (parameters in mm and radians side by side), its eigenvalues below ``RANK_TOL`` of
the largest left out; values that are not finite, or that neither half gives a variance,
are left out too. ``chi2_dof`` near 1: the halves agree as stated; well above: the stated
covariance is too small for what the halves see (a model that misses something that
differs between them, a noise underrated); well below: the stated std is larger than the
scatter. ``p_value`` is the chance of a chi2 this large if the covariances are right; the
halves' correlation and the RMS of their difference say the same in plain figures.

Two rules read a comparison: :meth:`Comparison.within` (chi2/dof at most a threshold: the
print's halves, ``config.as_printed.replication_max_chi2_dof``) and
:meth:`Comparison.agrees` (the noise floor's rule: significant *and* beyond what a
covariance is known to: the robot fit's halves, ``config.verdict``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from vision_cal.errors import VisionCalError

#: eigenvalues of the unit-diagonal difference covariance below this share of the largest
#: are directions neither half states (the rank)
RANK_TOL = 1e-9


@dataclass(frozen=True)
class Comparison:
    """Two estimates compared (:func:`compare`).

    ``n``: values given; ``dof``: the rank of the difference's covariance (the chi-square's
    degrees of freedom); ``chi2`` and ``chi2_dof`` (``chi2 / dof``; NaN when ``dof`` is 0);
    ``p_value``: the chance of a ``chi2`` at least this large were the stated covariances
    right; ``rms_diff``: RMS of ``a - b`` over the values (per value, not per point);
    ``correlation``: Pearson's correlation of ``a`` and ``b`` over the values (NaN when
    either is constant)."""

    n: int
    dof: int
    chi2: float
    chi2_dof: float
    p_value: float
    rms_diff: float
    correlation: float

    def within(self, max_chi2_dof: float) -> bool:
        """``chi2_dof`` at most ``max_chi2_dof`` (False when not finite)."""
        return bool(math.isfinite(self.chi2_dof) and self.chi2_dof <= max_chi2_dof)

    def agrees(self, alpha: float, ratio_tol: float) -> bool:
        """The halves agree unless ``p_value`` is below ``alpha`` *and* ``chi2_dof`` above
        ``ratio_tol ** 2`` (the noise floor's rule: a covariance is known only that well)."""
        return not (self.dof > 0 and self.p_value < alpha and self.chi2_dof > ratio_tol**2)

    def to_json(self) -> dict:
        """calibration.json's ``chi2``, ``dof``, ``chi2_dof`` and ``p`` (docs/format.md,
        ``replication``)."""
        return {"chi2": self.chi2, "dof": self.dof, "chi2_dof": self.chi2_dof,
                "p": self.p_value}


def _cov(c, n: int) -> np.ndarray:
    c = np.asarray(c, float)
    if c.ndim == 0:
        return float(c) * np.eye(n)
    if c.ndim == 1:
        if c.shape != (n,):
            raise VisionCalError(f"variances of shape {c.shape} for {n} values")
        return np.diag(c)
    if c.shape != (n, n):
        raise VisionCalError(f"covariances of shape {c.shape} for {n} values")
    return c


def compare(a, cov_a, b, cov_b) -> Comparison:
    """Chi-square of ``a - b`` against ``cov_a + cov_b`` (module docstring)."""
    a = np.asarray(a, float).ravel()
    b = np.asarray(b, float).ravel()
    if a.shape != b.shape:
        raise VisionCalError(f"the halves differ in size: {a.size} and {b.size} values")
    n = a.size
    d = a - b
    C = _cov(cov_a, n) + _cov(cov_b, n)
    C = 0.5 * (C + C.T)
    rms = float(np.sqrt(np.mean(d[np.isfinite(d)] ** 2))) if np.isfinite(d).any() else math.nan
    fin = np.isfinite(a) & np.isfinite(b)
    sa, sb = (np.std(a[fin]), np.std(b[fin])) if fin.sum() > 1 else (0.0, 0.0)
    corr = float(np.corrcoef(a[fin], b[fin])[0, 1]) if sa > 0 and sb > 0 else math.nan
    none = Comparison(n, 0, 0.0, math.nan, math.nan, rms, corr)
    diag = np.diag(C)
    ok = np.isfinite(d) & np.isfinite(diag) & (diag > 0)
    if not ok.any():
        return none
    d, C = d[ok], C[np.ix_(ok, ok)]
    if not np.all(np.isfinite(C)):
        return none
    s = np.sqrt(np.diag(C))
    w, V = np.linalg.eigh(C / np.outer(s, s))
    keep = w > RANK_TOL * max(float(w.max()), 0.0)
    dof = int(keep.sum())
    if dof == 0:
        return none
    z = V[:, keep].T @ (d / s)
    chi2 = float(np.sum(z**2 / w[keep]))
    return Comparison(n, dof, chi2, chi2 / dof, float(stats.chi2.sf(chi2, dof)), rms, corr)
