"""How well a calibrated model is expected to hit a point: covariance -> std in mm.

``calibration.json`` carries the fit's full parameter covariance (added field, read and
written by :mod:`vision_cal.dataset.covariance`). A command ``q`` planned with the calibrated
model lands, on the true robot, at ``f_true(q) = f_hat(q) - J_theta(q) dtheta`` to first
order (``J_theta`` the model's Jacobian at the command, the compensated IK Jacobian's
other half), so the miss has covariance ``J Sigma J^T`` and :func:`predicted_std_mm` is
its per-axis standard deviation ``sqrt(trace / 2)``, the convention of ``sigma_mm``.
"""

from __future__ import annotations

import numpy as np


def predicted_std_mm(model, cov, q_deg, approach=None) -> np.ndarray:
    """(N,) per-axis std (mm) of where commands ``q_deg`` (N, 2) (or (N, 3) with joint 4)
    land, from ``cov``."""
    q = np.asarray(q_deg, dtype=float)
    q = q.reshape(-1, 3 if q.ndim == 2 and q.shape[-1] == 3 else 2)
    out = np.full(len(q), np.nan)
    ok = np.all(np.isfinite(q), axis=1)
    if not ok.any():
        return out
    s = None if approach is None else np.asarray(approach, dtype=float).reshape(len(q), -1)[ok]
    J = model.jacobian(q[ok], s)                                   # (n, 2, P)
    C = np.einsum("nip,pq,njq->nij", J, np.asarray(cov, float), J)
    out[ok] = np.sqrt(np.clip(np.trace(C, axis1=1, axis2=2), 0.0, None) / 2)
    return out
