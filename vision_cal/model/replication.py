"""Replication: the same quantity from two independent halves of the data, compared against
the covariance each half states (issue 37; mrcal's cross-validation diff is the idea).

If each half's estimate ``a``, ``b`` (n,) has the stated covariance ``cov_a``, ``cov_b`` and
the halves share no data, their difference has covariance ``cov_a + cov_b``, and

    chi2 = (a - b)' (cov_a + cov_b)^+ (a - b)

is chi-square with ``dof`` = the rank of that sum (a gauge, such as a layout's similarity
removed from both, leaves it singular: the pseudo-inverse over its range). ``chi2 / dof``
near 1: the halves agree as stated; well above 1: they disagree beyond what each claims
(a stated std too small, or a model the halves see differently); well below 1: the stated
std is larger than the scatter. The halves' correlation and the RMS of their difference
say the same in plain figures.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.stats import chi2 as _chi2


@dataclass(frozen=True)
class Comparison:
    """Two estimates compared (:func:`compare`).

    ``n``: values compared; ``dof``: the rank of the difference's covariance (the chi-square's
    degrees of freedom); ``chi2`` and ``chi2_dof`` (``chi2 / dof``; NaN when ``dof`` is 0);
    ``p_value``: the chance of a ``chi2`` at least this large were the stated covariances
    right; ``rms_diff``: RMS of ``a - b`` over the ``n`` values (per value, not per point);
    ``correlation``: Pearson's correlation of ``a`` and ``b`` over the values (NaN when
    either is constant)."""

    n: int
    dof: int
    chi2: float
    chi2_dof: float
    p_value: float
    rms_diff: float
    correlation: float

    def agrees(self, max_chi2_dof: float) -> bool:
        """The halves agree: ``chi2_dof`` at most ``max_chi2_dof`` (False when not finite)."""
        return bool(math.isfinite(self.chi2_dof) and self.chi2_dof <= max_chi2_dof)

    def to_json(self) -> dict:
        """The fields by name (floats; NaN stays NaN)."""
        return {k: (float(v) if isinstance(v, float) else int(v))
                for k, v in asdict(self).items()}


def _cov(c, n: int) -> np.ndarray:
    c = np.asarray(c, float)
    if c.ndim == 0:
        return float(c) * np.eye(n)
    if c.ndim == 1:
        if c.shape != (n,):
            raise ValueError(f"variances of shape {c.shape}, expected ({n},)")
        return np.diag(c)
    if c.shape != (n, n):
        raise ValueError(f"covariance of shape {c.shape}, expected ({n}, {n})")
    return c


def compare(a, cov_a, b, cov_b, *, rtol: float = 1e-9) -> Comparison:
    """``a`` and ``b`` (any shape, flattened to n values, the same order) with their
    covariances ``cov_a``, ``cov_b``: (n, n), or (n,) variances, or one variance for all.
    Directions where ``cov_a + cov_b`` has an eigenvalue below ``rtol`` times its largest
    are outside its range (a gauge) and left out of ``chi2`` and ``dof``."""
    a = np.asarray(a, float).ravel()
    b = np.asarray(b, float).ravel()
    if a.shape != b.shape:
        raise ValueError(f"the halves differ in size: {a.size} and {b.size} values")
    n = a.size
    d = a - b
    S = _cov(cov_a, n) + _cov(cov_b, n)
    S = 0.5 * (S + S.T)
    if n == 0 or not np.all(np.isfinite(S)) or not np.all(np.isfinite(d)):
        return Comparison(n, 0, math.nan, math.nan, math.nan,
                          float(np.sqrt(np.mean(d**2))) if n else math.nan, math.nan)
    w, V = np.linalg.eigh(S)
    keep = w > rtol * max(float(w.max()), 0.0) if w.max() > 0 else np.zeros(n, bool)
    z = V[:, keep].T @ d
    c2 = float(np.sum(z**2 / w[keep]))
    dof = int(keep.sum())
    sa, sb = np.std(a), np.std(b)
    corr = (float(np.corrcoef(a, b)[0, 1]) if n > 1 and sa > 0 and sb > 0 else math.nan)
    return Comparison(n, dof, c2, c2 / dof if dof else math.nan,
                      float(_chi2.sf(c2, dof)) if dof else math.nan,
                      float(np.sqrt(np.mean(d**2))), corr)
