"""How well a calibrated model is expected to hit a point: the std of where a planned
target lands, in mm, by part.

``calibration.json`` carries the fit's full parameter covariance (added field, read and
written by :mod:`vision_cal.dataset.covariance`). A command ``q`` planned with the calibrated
model lands, on the true robot, at ``f_true(q) = f_hat(q) - J_theta(q) dtheta`` to first
order (``J_theta`` the model's Jacobian at the command, the compensated IK Jacobian's
other half), so the miss has covariance ``J Sigma J^T`` and :func:`predicted_std_mm` is
its per-axis standard deviation ``sqrt(trace / 2)``, the convention of ``sigma_mm``.

That is the calibration's part only. Where the target lands also moves by the robot's
repeatability, by what the model leaves unexplained, by the print under the marks and, off
the paper, by the paper's scale: :func:`target_std` adds them (calibration.json
``verdict.target_std``: the repeatability, the unexplained part and the print, the same at
every target; ``paper_scale``: ``scale_std`` times how far the target lies outside the
paper), each in its own column of plan.csv, ``std_mm`` their root sum of squares: the
1-sigma of the miss, per axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vision_cal.estimate.paper_scale import outside_mm


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


#: plan.csv's columns of a target's std, by part (mm, per axis, one std), after ``std_mm``
STD_PARTS = ("std_calibration_mm", "std_repeatability_mm", "std_unexplained_mm",
             "std_print_mm", "std_paper_scale_mm")


@dataclass(frozen=True)
class TargetStd:
    """Each planned target's std by part (mm, per axis, one std; arrays (N,)):
    ``calibration_mm`` (:func:`predicted_std_mm`), ``repeatability_mm``,
    ``unexplained_mm`` and ``print_mm`` (calibration.json ``verdict.target_std``, the same
    at every target), ``paper_scale_mm`` (``paper_scale.scale_std`` times the distance
    outside the paper, 0 on it)."""

    calibration_mm: np.ndarray
    repeatability_mm: np.ndarray
    unexplained_mm: np.ndarray
    print_mm: np.ndarray
    paper_scale_mm: np.ndarray

    @property
    def total_mm(self) -> np.ndarray:
        """(N,) the root sum of squares of the parts: the 1-sigma of the miss, per axis."""
        return np.sqrt(self.calibration_mm**2 + self.repeatability_mm**2
                       + self.unexplained_mm**2 + self.print_mm**2 + self.paper_scale_mm**2)

    def rows(self) -> list[dict]:
        """plan.csv's ``std_mm`` and :data:`STD_PARTS` for each target (NaN: unknown)."""
        cols = (self.total_mm, self.calibration_mm, self.repeatability_mm,
                self.unexplained_mm, self.print_mm, self.paper_scale_mm)
        return [dict(zip(("std_mm",) + STD_PARTS, (float(c[i]) for c in cols)))
                for i in range(len(self.total_mm))]


def target_std(model, cov, q_deg, approach, target_mm, doc: dict) -> TargetStd:
    """The std of where commands ``q_deg`` (N, 2|3) with ``approach`` land, planned for
    ``target_mm`` (N, 2) with the model of calibration.json ``doc`` (``cov`` its covariance,
    internal units). A file written before ``verdict.target_std`` gives the verdict's
    ``repeatability_mm`` alone beside the covariance."""
    n = len(np.asarray(target_mm, float).reshape(-1, 2))
    cal = predicted_std_mm(model, cov, q_deg, approach)
    v = doc.get("verdict") if isinstance(doc.get("verdict"), dict) else {}
    parts = v.get("target_std") if isinstance(v.get("target_std"), dict) else {}

    def const(key, fallback=0.0):
        x = parts.get(key, fallback)
        x = x if isinstance(x, (int, float)) and math.isfinite(x) else 0.0
        return np.full(n, float(x))

    rep = const("repeatability_mm", v.get("repeatability_mm") or 0.0)
    ps = doc.get("paper_scale") if isinstance(doc.get("paper_scale"), dict) else {}
    kappa, ext = ps.get("scale_std"), ps.get("sheet_extent_mm")
    scale = np.zeros(n)
    if isinstance(kappa, (int, float)) and ext is not None and n:
        d = outside_mm(target_mm, ext)
        scale = float(kappa) * np.sqrt(np.sum(d**2, axis=1) / 2)
    return TargetStd(cal, rep, const("unexplained_mm"), const("print_mm"), scale)
