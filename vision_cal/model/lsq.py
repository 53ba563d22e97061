"""General least-squares calibration of the model (base parameters plus effects).

``Fit.from_estimate(q_deg, xy_mm, approach=..., model=...)`` fits every free parameter of
``model`` (the base model when ``model`` has no effects) to marks anywhere:

- the start comes from the closed-form linear solve (:mod:`vision_cal.model.linear`),
  so the solve never depends on the nominal model being close; effects start at zero;
- the one solver (:func:`vision_cal.model.solve.solve`: MINPACK's Levenberg-Marquardt) with
  the analytic Jacobian of :class:`vision_cal.model.robot.RobotModel`; a solve that stops on
  its evaluation limit is a :class:`FailedFit` with that reason;
- a robust pass (soft-L1 loss scaled to the residual spread) names outliers (normalised
  residual above ``outlier_sigma``), which are left out of the final solve;
- identifiability is checked on the column-scaled Jacobian (rank and condition number)
  *before* any number is reported: a fit that cannot be made (too few marks, a degenerate
  plan, confounded parameters) is returned as a :class:`FailedFit`, falsy, whose ``reason``
  names the problem (as ``skimage.measure.fit`` returns a ``FailedEstimation``); callers
  that branch on it test ``if not fit``, callers that cannot go on raise
  :class:`vision_cal.errors.CalibrationError` with that reason (:meth:`FailedFit.or_raise`);
- standard deviations from the one covariance policy (:func:`vision_cal.model.solve.covariance`,
  scaled by the residual variance ``s^2 = SSR / (2N - P)``; a direction the data do not fix
  is a :class:`FailedFit` naming its parameters), and correlations (pairs above 0.9 are
  flagged).

Thresholds (outlier rule, condition number limit): the ``config`` passed in
(:class:`vision_cal.config.EstimatorConfig`, default :data:`vision_cal.config.DEFAULT`).
Weights: ``sigma_mm`` (N,) per-mark measurement standard deviations, if known.
Joints ``(N, 3)`` carry joint 4 (``[q1, q2, q4]``, for a model with a tool, see
:mod:`vision_cal.model.robot`); the linear start uses joints 1 and 2 only.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from vision_cal.model.linear import explain_degeneracy, linear_init
from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.errors import CalibrationError, Failure
from vision_cal.model.kinematics import ScaraParams
from vision_cal.model.robot import RobotModel, Tool
from vision_cal.model.rms import rms_2d
from vision_cal.model.solve import covariance, solve



@dataclass(frozen=True)
class FailedFit(Failure):
    """A fit that could not be made, and why. Falsy, so ``if not fit`` branches on it;
    reading a fit's attribute from it raises with the reason (:class:`~vision_cal.errors.Failure`)."""

    reason: str

    def or_raise(self):
        """End the run: :class:`CalibrationError` with the reason."""
        raise CalibrationError(self.reason)


@dataclass(frozen=True)
class Fit:
    """A calibrated model with its uncertainty. Arrays are over the fitted marks."""

    model: RobotModel
    cov: np.ndarray              # (P, P) in internal units (mm, rad, scale)
    labels: tuple[str, ...]      # (P,)
    residuals_mm: np.ndarray     # (N, 2) measured minus predicted, all marks given
    inliers: np.ndarray          # (N,) bool: used in the final solve
    ids: tuple[str, ...]         # (N,)
    cond: float                  # condition number of the column-scaled Jacobian
    rank: int
    residual_scale: float        # sqrt(SSR/dof) of the weighted residuals, per axis: mm when
                                 # unweighted, a ratio to the given sigma_mm when weighted
    dof: int
    initial: ScaraParams
    n_params: int = 0
    notes: tuple[str, ...] = field(default=())

    # -- construction -------------------------------------------------------------------
    @classmethod
    def from_estimate(cls, q_deg, xy_mm, *, approach=None, model: RobotModel | None = None,
                      sigma_mm=None, ids=None, robust: bool = True,
                      config: EstimatorConfig | None = None) -> "Fit | FailedFit":
        """The fit, or a :class:`FailedFit` saying why none can be made. Raises
        :class:`CalibrationError` only for inputs that are wrong (lengths, NaN)."""
        config = config or DEFAULT
        outlier_sigma = config.selection.outlier_sigma
        cond_limit = config.fit.condition_number_limit
        q = np.asarray(q_deg, dtype=float)
        q = q.reshape(-1, 3 if q.ndim == 2 and q.shape[-1] == 3 else 2)  # [q1, q2(, q4)]
        xy = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
        n = len(q)
        if len(xy) != n:
            raise CalibrationError(f"{n} poses but {len(xy)} measured marks")
        if not np.all(np.isfinite(xy)) or not np.all(np.isfinite(q)):
            raise CalibrationError("non-finite joint angles or mark positions")
        s_app = (np.ones((n, 2)) if approach is None
                 else np.asarray(approach, float).reshape(n, -1))
        ids = tuple(ids) if ids is not None else tuple(f"#{i}" for i in range(n))
        w = np.ones(n) if sigma_mm is None else 1.0 / np.asarray(sigma_mm, dtype=float)
        why = explain_degeneracy(q[:, :2])
        if why:
            return FailedFit(why)
        init = linear_init(q[:, :2], xy)
        base = model if model is not None else RobotModel(init)
        start = RobotModel(init, tuple(e if isinstance(e, Tool)  # a tool starts as given
                                       else e.with_theta(np.zeros_like(e.theta))
                                       for e in base.effects))
        P = len(start.vector)
        if 2 * n <= P:
            return FailedFit(f"{n} marks give {2 * n} equations for {P} unknowns "
                             f"({', '.join(start.param_labels())}): more marks are needed")
        labels = tuple(start.param_labels())
        J0 = (start.jacobian(q, s_app) * w[:, None, None]).reshape(-1, P)
        c0 = covariance(J0, labels=labels, cond_limit=cond_limit)
        if c0.not_fixed:
            return FailedFit(_confounded(c0))

        def fun(v, keep):
            m = start.with_vector(v)
            r = (m.predict(q[keep], s_app[keep]) - xy[keep]) * w[keep, None]
            return r.ravel()

        def jac(v, keep):
            m = start.with_vector(v)
            return (m.jacobian(q[keep], s_app[keep]) * w[keep, None, None]).reshape(-1, P)

        def solved(x0, keep, **robust_loss):
            return solve(lambda v: fun(v, keep), x0, jac=lambda v: jac(v, keep),
                         **robust_loss)

        keep = np.ones(n, dtype=bool)
        sol = solved(start.vector, keep)
        notes = []
        if sol and robust and n * 2 - P >= 4:
            r = sol.residuals.reshape(-1, 2)
            scale = 1.4826 * np.median(np.abs(r)) + 1e-12
            if np.any(np.abs(r) > outlier_sigma * scale):
                rob = solved(sol.x, keep, loss="soft_l1", f_scale=2.0 * scale)
                if not rob:
                    return FailedFit(f"the robust pass: {rob.reason}")
                r = rob.residuals.reshape(-1, 2)
                scale = 1.4826 * np.median(np.abs(r)) + 1e-12
                bad = np.hypot(r[:, 0], r[:, 1]) > outlier_sigma * scale * np.sqrt(2)
                if bad.any() and (n - bad.sum()) * 2 > P + 2:
                    keep = ~bad
                    notes.append("outliers left out: " + ", ".join(
                        ids[i] for i in np.flatnonzero(bad)))
                    sol = solved(rob.x, keep)
        if not sol:
            return FailedFit(sol.reason)
        fitted = start.with_vector(sol.x)
        s2 = sol.residual_variance
        cov = sol.covariance(labels, cond_limit=cond_limit)
        if cov.not_fixed:
            return FailedFit(_confounded(cov))
        residuals = xy - fitted.predict(q, s_app)
        return cls(fitted, cov.matrix, labels, residuals, keep, ids, cov.cond, cov.rank,
                   float(np.sqrt(s2)) if np.isfinite(s2) else float("nan"), sol.dof, init, P,
                   tuple(notes))

    def or_raise(self) -> "Fit":
        """This fit (the twin of :meth:`FailedFit.or_raise`)."""
        return self

    def with_shared_error(self, q_deg, approach, cov_mm2, sigma_mm=None) -> "Fit":
        """This fit with the parameters' covariance grown by an error the marks share
        (``cov_mm2`` (2N, 2N) over the fit's N marks, rows x0, y0, x1, ...: the print's
        correlated part, :func:`vision_cal.measure.print_stage.print_field_cov`): the
        solve's linear response ``G = (J'WJ)^-1 J'W`` (inlier rows, the weights
        ``1 / sigma_mm^2`` the fit used) carries it, ``cov + G C G'``. The residual's scale
        ``s^2`` does not: an error the parameters take up leaves no residual."""
        q = np.asarray(q_deg, float)
        q = q.reshape(-1, 3 if q.ndim == 2 and q.shape[-1] == 3 else 2)
        app = (np.ones((len(q), 2)) if approach is None
               else np.asarray(approach, float).reshape(len(q), -1))
        keep = np.asarray(self.inliers, bool)
        w = np.ones(len(q)) if sigma_mm is None else 1.0 / np.asarray(sigma_mm, float)
        P = len(self.model.vector)
        w2 = np.repeat(w[keep], 2)
        Jw = self.model.jacobian(q[keep], app[keep]).reshape(-1, P) * w2[:, None]
        rows = np.column_stack([2 * np.flatnonzero(keep), 2 * np.flatnonzero(keep) + 1]).ravel()
        Cw = np.asarray(cov_mm2, float)[np.ix_(rows, rows)] * np.outer(w2, w2)
        shared = covariance(Jw, labels=self.labels, meat=Jw.T @ Cw @ Jw)
        return replace(self, cov=self.cov + shared.matrix)

    # -- results --------------------------------------------------------------------------
    @property
    def sigma_mm(self) -> float:
        """Old name of :attr:`residual_scale` (``sigma_mm`` is a mark's measurement std)."""
        return self.residual_scale

    @property
    def params(self) -> ScaraParams:
        return self.model.params

    @property
    def std(self) -> np.ndarray:
        """(P,) one standard deviation of each parameter, internal units."""
        return np.sqrt(np.clip(np.diag(self.cov), 0.0, None))

    @property
    def base_std_json(self) -> dict:
        """The ``std`` block of calibration.json (mm and degrees)."""
        s = self.std
        return {"L1_mm": s[0], "L2_mm": s[1], "joint_zero_deg": [np.degrees(s[2]),
                                                                  np.degrees(s[3])],
                "base_mm": [s[4], s[5]]}

    @property
    def correlation(self) -> np.ndarray:
        s = self.std
        with np.errstate(invalid="ignore", divide="ignore"):
            c = self.cov / np.outer(s, s)
        return c

    def high_correlations(self, limit: float = 0.9) -> list[tuple[str, str, float]]:
        c = self.correlation
        out = []
        for i in range(len(c)):
            for j in range(i + 1, len(c)):
                if np.isfinite(c[i, j]) and abs(c[i, j]) > limit:
                    out.append((self.labels[i], self.labels[j], float(c[i, j])))
        return out

    @property
    def rms_mm(self) -> float:
        """RMS of the 2-D residual over the inlier marks (mm)."""
        r = self.residuals_mm[self.inliers]
        return rms_2d(r)

    def predict(self, q_deg, approach=None) -> np.ndarray:
        return self.model.predict(q_deg, approach)

    def residuals(self, q_deg, xy_mm, approach=None) -> np.ndarray:
        """Measured minus predicted (N, 2) for other marks (e.g. held-out)."""
        return np.asarray(xy_mm, dtype=float) - self.predict(q_deg, approach)


def _confounded(cov) -> str:
    """The reason of a fit whose ``cov`` (:class:`vision_cal.model.solve.Covariance`) has a
    direction the data do not fix: its smallest, by the (at most four) parameters it moves."""
    return ("the plan cannot tell these parameters apart (condition number "
            f"{cov.cond:.3g}): {' ~ '.join(cov.not_fixed[-1].labels[:4])}")
