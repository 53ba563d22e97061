"""How well a calibrated model is expected to hit a point: covariance -> std in mm.

``calibration.json`` carries the fit's full parameter covariance (added field)::

    "covariance": {"params": ["L1_mm", "L2_mm", "z1_deg", "z2_deg", "base_x_mm",
                              "base_y_mm", "joint_backlash(joint 2).deg", ...],
                   "matrix": [[...], ...]}

in file units (mm, degrees, unitless scale). A command ``q`` planned with the calibrated
model lands, on the true robot, at ``f_true(q) = f_hat(q) - J_theta(q) dtheta`` to first
order (``J_theta`` the model's Jacobian at the command, the compensated IK Jacobian's
other half), so the miss has covariance ``J Sigma J^T`` and :func:`predicted_std_mm` is
its per-axis standard deviation ``sqrt(trace / 2)``, the convention of ``sigma_mm``.

Without ``covariance`` (files written before it existed) the ``std`` block's diagonal is
used for the six base parameters, correlations ignored (said in a warning).
"""

from __future__ import annotations

import logging

import numpy as np

from vision_cal.errors import VisionCalError

log = logging.getLogger(__name__)


def _file_labels_and_scale(labels) -> tuple[list[str], np.ndarray]:
    """File names of the model's internal parameter labels and internal->file factors."""
    out, scale = [], []
    for lab in labels:
        if lab in ("z1", "z2"):
            out.append(f"{lab}_deg")
            scale.append(np.degrees(1.0))
        elif lab.endswith(".deg") or lab.endswith("_deg"):
            out.append(lab)
            scale.append(np.degrees(1.0))
        else:
            out.append(lab)
            scale.append(1.0)
    return out, np.array(scale)


def covariance_json(labels, cov_internal) -> dict:
    """The ``covariance`` field of calibration.json from a fit's internal covariance."""
    names, s = _file_labels_and_scale(labels)
    c = np.asarray(cov_internal, dtype=float) * np.outer(s, s)
    return {"params": names, "matrix": c.tolist()}


def load_covariance(doc: dict, model, *, file: str | None = None) -> np.ndarray:
    """Internal-unit covariance (P, P) matching ``model.vector`` from a calibration doc."""
    names, s = _file_labels_and_scale(model.param_labels())
    block = doc.get("covariance")
    if block is not None:
        try:
            got = list(block["params"])
            m = np.asarray(block["matrix"], dtype=float)
        except (KeyError, TypeError, ValueError) as e:
            raise VisionCalError(f"malformed covariance: {e}", file=file,
                                 field="covariance") from e
        if m.shape != (len(got), len(got)):
            raise VisionCalError(f"expected a {len(got)}x{len(got)} matrix, got {m.shape}",
                                 file=file, field="covariance.matrix")
        idx = {n: i for i, n in enumerate(got)}
        missing = [n for n in names if n not in idx]
        if missing:
            raise VisionCalError(f"has no entry for {', '.join(missing)} (the model's "
                                 "parameters)", file=file, field="covariance.params")
        k = [idx[n] for n in names]
        return m[np.ix_(k, k)] / np.outer(s, s)
    std = doc.get("std")
    if not isinstance(std, dict):
        raise VisionCalError("missing: neither covariance nor std is given", file=file,
                             field="std")
    log.warning("%s: no covariance: predicted std from the base parameters' std only "
                "(correlations and effects ignored)", file)
    try:
        d = [std["L1_mm"], std["L2_mm"], std["joint_zero_deg"][0], std["joint_zero_deg"][1],
             std["base_mm"][0], std["base_mm"][1]]
        d = np.asarray(d, dtype=float)
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise VisionCalError(f"malformed std: {e}", file=file, field="std") from e
    cov = np.zeros((len(names), len(names)))
    cov[:6, :6] = np.diag((d / s[:6]) ** 2)
    return cov


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
