"""Replication: the same quantity from two independent halves of the data, against what each
half states (issue 37, "Numbers that hold").

:func:`compare` takes two estimates ``a``, ``b`` (K,) of one quantity and the covariance each
states, ``cov_a``, ``cov_b`` (K, K). The halves are independent, so if each covariance is
right their difference ``d = a - b`` has covariance ``C = cov_a + cov_b`` and

    chi2 = d' C^+ d        is chi-square with  dof = rank(C)

degrees of freedom (``C^+`` the pseudo-inverse on the directions ``C`` states: a gauge the
halves share, or positions that only ``P < K`` parameters move, leave ``C`` singular). The
rank is read on ``C`` scaled to unit diagonal (parameters in mm and radians side by side),
its eigenvalues below ``RANK_TOL`` of the largest left out. ``chi2_dof`` near 1: the halves
agree as stated; well above: the stated covariance is too small for what the halves see (a
model that misses something that differs between them, a noise underrated); ``p`` the
chance of a chi2 this large if the covariances are right. mrcal's cross-validation diff is
the same idea for a camera's projection.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from vision_cal.errors import VisionCalError

#: eigenvalues of the unit-diagonal difference covariance below this share of the largest
#: are directions neither half states (the rank)
RANK_TOL = 1e-9


@dataclass(frozen=True)
class Replication:
    """Two halves' estimates against their stated covariances (:func:`compare`)."""

    chi2: float
    dof: int
    chi2_dof: float         # chi2 / dof (NaN without dof)
    p: float                # chi2.sf(chi2, dof) (NaN without dof)

    def agrees(self, alpha: float, ratio_tol: float) -> bool:
        """The halves agree unless ``p`` is below ``alpha`` *and* ``chi2_dof`` above
        ``ratio_tol ** 2`` (the noise floor's rule: a covariance is known only that well)."""
        return not (self.dof > 0 and self.p < alpha and self.chi2_dof > ratio_tol**2)

    def to_json(self) -> dict:
        return {"chi2": self.chi2, "dof": self.dof, "chi2_dof": self.chi2_dof, "p": self.p}


def compare(a, cov_a, b, cov_b) -> Replication:
    """Chi-square of ``a - b`` (K,) against ``cov_a + cov_b`` (K, K) (module docstring)."""
    d = np.asarray(a, float).reshape(-1) - np.asarray(b, float).reshape(-1)
    C = np.asarray(cov_a, float) + np.asarray(cov_b, float)
    k = len(d)
    if C.shape != (k, k):
        raise VisionCalError(f"covariances of shape {C.shape} for {k} values")
    ok = np.isfinite(d) & np.isfinite(np.diag(C)) & (np.diag(C) > 0)
    if not ok.any():
        return Replication(0.0, 0, float("nan"), float("nan"))
    d, C = d[ok], C[np.ix_(ok, ok)]
    s = np.sqrt(np.diag(C))
    w, V = np.linalg.eigh(C / np.outer(s, s))
    keep = w > RANK_TOL * max(float(w.max()), 0.0)
    dof = int(keep.sum())
    if dof == 0:
        return Replication(0.0, 0, float("nan"), float("nan"))
    z = V[:, keep].T @ (d / s)
    chi2 = float(np.sum(z**2 / w[keep]))
    return Replication(chi2, dof, chi2 / dof, float(stats.chi2.sf(chi2, dof)))
