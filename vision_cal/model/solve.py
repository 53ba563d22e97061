"""The one least-squares solver and the one covariance policy of every fit.

    sol = solve(residual, x0, jac=jacobian, free=mask)        # a Solution, or falsy
    if not sol:
        raise CalibrationError(sol.reason)                    # stopped on a limit, non-finite
    cov = sol.covariance(labels)                              # s^2 = SSR / dof
    cov.std                                                   # inf where the data fix nothing

As mrcal's ``optimize`` poses every problem to one solver by which parameters are free, a
fit here is a residual (M,) of the full parameter vector (P,), its Jacobian (M, P) (dense,
or sparse for problems with many local unknowns), a start and a mask of the free entries;
the fixed ones keep their start. :func:`solve` is scipy's ``least_squares`` (MINPACK's
Levenberg-Marquardt for a plain dense problem, its trust-region reflective method with a
robust loss, bounds or a sparse Jacobian). A solve that stops on its evaluation limit did not
converge: it is a :class:`StoppedSolve`, falsy with the reason (as a
:class:`vision_cal.model.lsq.FailedFit`); where it stopped is still readable as ``last``
for a caller that needs only what a few steps leave (the sheet-fit gate).

**The covariance policy** (:func:`covariance`, ``docs/conventions.md`` "Uncertainty"):

- the Jacobian's columns are scaled to unit norm (so millimetres, radians and pixels
  compare) and decomposed (SVD); a singular value below the largest over the condition limit
  (``config.fit.condition_number_limit``, 1e8) is a direction the data do not fix;
- such a direction is *reported*, never given the small std a pseudo-inverse gives it: it
  is named by the labels of the parameters it moves (:class:`NotFixed`), those parameters'
  std are infinite (``null`` in a file), and a derived quantity whose gradient moves along
  it has an infinite std too (:meth:`Covariance.std_of`); along the directions the data fix
  the covariance is ``s^2 (J^T J)^-1``;
- ``s^2``: the residual variance ``SSR / (M - P_free)`` (the default), or a noise the caller
  gives (1 when the residuals are already in units of their std);
- a caller with a noise model of its own (correlated residuals ``Sigma``) gives its
  ``meat = J^T Sigma J``: the sandwich ``(J^T J)^-1 meat (J^T J)^-1``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.optimize import least_squares

from vision_cal.config import DEFAULT
from vision_cal.errors import Failure, VisionCalError

#: a parameter whose share of a not-fixed direction (column-scaled, unit vector) is above this
#: has an infinite std; below it the direction does not move the parameter
INVOLVED = 1e-6
#: a parameter is *named* for a not-fixed direction when its share is above this (the
#: direction mostly moves it)
NAMED = 0.2


@dataclass(frozen=True)
class NotFixed:
    """A direction of the parameters the data do not fix: ``labels`` the parameters it mostly
    moves (share above :data:`NAMED`, largest first), ``direction`` (P,) the unit vector in
    column-scaled coordinates, ``ratio`` its singular value over the largest."""

    labels: tuple[str, ...]
    direction: np.ndarray
    ratio: float

    def describe(self) -> str:
        return " ~ ".join(self.labels)


@dataclass(frozen=True)
class Covariance:
    """A fit's covariance under the one policy (module docstring). ``matrix`` (P, P) holds
    the directions the data fix (zero along the others, so it is finite and a gradient
    orthogonal to :attr:`not_fixed` propagates through it); ``scale`` (P,) the column scale
    used (1 / column norm); ``cond`` the condition number of the column-scaled Jacobian
    (inf when a column is zero) and ``rank`` the directions fixed."""

    matrix: np.ndarray
    labels: tuple[str, ...]
    not_fixed: tuple[NotFixed, ...]
    cond: float
    rank: int
    scale: np.ndarray

    @property
    def fixed(self) -> np.ndarray:
        """(P,) bool: the parameters no not-fixed direction moves."""
        ok = np.ones(len(self.labels), bool)
        for d in self.not_fixed:
            ok &= np.abs(d.direction) <= INVOLVED
        return ok

    @property
    def std(self) -> np.ndarray:
        """(P,) one standard deviation of each parameter; inf where the data fix nothing."""
        s = np.sqrt(np.clip(np.diag(self.matrix), 0.0, None))
        return np.where(self.fixed, s, np.inf)

    @property
    def stated(self) -> np.ndarray:
        """:attr:`matrix` with its diagonal the stated variances (:attr:`std` squared, inf
        where the data fix nothing): for a caller that keeps a plain matrix."""
        out = self.matrix.copy()
        out[np.diag_indices(len(out))] = self.std ** 2
        return out

    def std_of(self, G) -> np.ndarray:
        """(K,) std of the quantities ``G @ x`` (``G`` (K, P), the gradients): inf for a row
        that moves along a not-fixed direction."""
        G = np.atleast_2d(np.asarray(G, float))
        s = np.sqrt(np.clip(np.einsum("kp,pq,kq->k", G, self.matrix, G), 0.0, None))
        Gs = G * self.scale
        norm = np.maximum(np.linalg.norm(Gs, axis=1), 1e-300)
        for d in self.not_fixed:
            s = np.where(np.abs(Gs @ d.direction) > INVOLVED * norm, np.inf, s)
        return s

    def reason(self) -> str:
        """One line naming what the data cannot tell apart (empty when everything is fixed);
        the smallest direction first."""
        return "; ".join(d.describe() for d in reversed(self.not_fixed))


def covariance(J, *, labels=None, s2: float = 1.0, meat=None,
               cond_limit: float | None = None) -> Covariance:
    """The covariance of a least-squares fit with Jacobian ``J`` (M, P) at the solution
    (dense or sparse; rows weighted as the fit weighed them), under the one policy (module
    docstring): ``s2 (J^T J)^-1`` over the directions the data fix, or the sandwich
    ``(J^T J)^-1 meat (J^T J)^-1`` when ``meat`` (P, P) ``= J^T Sigma J`` is given; the
    directions whose column-scaled singular value is below the largest over ``cond_limit``
    (default ``config.DEFAULT.fit.condition_number_limit``) reported in ``not_fixed``."""
    J = J.toarray() if sparse.issparse(J) else np.asarray(J, float)
    P = J.shape[1]
    labels = tuple(labels) if labels is not None else tuple(f"p{i}" for i in range(P))
    if len(labels) != P:
        raise VisionCalError(f"{len(labels)} labels for {P} parameters")
    limit = float(cond_limit if cond_limit is not None else DEFAULT.fit.condition_number_limit)
    norms = np.linalg.norm(J, axis=0)
    sc = 1.0 / np.where(norms > 0, norms, 1.0)
    _, sv, vt = np.linalg.svd(J * sc, full_matrices=False)
    if len(sv) < P:                      # fewer rows than parameters
        sv = np.r_[sv, np.zeros(P - len(sv))]
        vt = np.vstack([vt, _complement(vt, P)])
    top = sv[0] if len(sv) and sv[0] > 0 else 0.0
    keep = sv > top / limit if top > 0 else np.zeros(P, bool)
    cond = float(top / sv[-1]) if sv[-1] > 0 else float("inf")
    Vf = vt[keep].T * sc[:, None]                      # (P, r): scaled back
    bread = (Vf / sv[keep] ** 2) @ Vf.T
    if meat is None:
        matrix = bread * float(s2)
    else:
        matrix = bread @ np.asarray(meat, float) @ bread
    not_fixed = []
    for k in np.flatnonzero(~keep):
        v = vt[k]
        order = np.argsort(-np.abs(v))
        named = tuple(labels[i] for i in order if abs(v[i]) > NAMED)
        not_fixed.append(NotFixed(named, v.copy(), float(sv[k] / top) if top > 0 else 0.0))
    return Covariance(matrix, labels, tuple(not_fixed), cond, int(keep.sum()), sc)


def _complement(vt: np.ndarray, P: int) -> np.ndarray:
    """Rows completing ``vt``'s (r, P) orthonormal rows to a basis of R^P."""
    q, _ = np.linalg.qr(np.vstack([vt, np.eye(P)]).T)
    return q[:, len(vt):P].T


@dataclass(frozen=True)
class Solution:
    """A converged solve. ``x`` (P,) the full vector (fixed entries as started); ``free`` (P,)
    bool; ``residuals`` (M,) and ``jacobian`` (M, P_free) at ``x`` (the free columns,
    dense or sparse as the problem gave it); ``cost`` ``0.5 * residuals @ residuals`` (the
    plain cost, also after a robust solve); ``nfev`` residual evaluations; ``status``
    scipy's message."""

    x: np.ndarray
    free: np.ndarray
    residuals: np.ndarray
    jacobian: object
    cost: float
    nfev: int
    status: str

    def __bool__(self) -> bool:
        return True

    @property
    def dof(self) -> int:
        """Residuals less free parameters."""
        return int(len(self.residuals) - int(np.sum(self.free)))

    @property
    def ssr(self) -> float:
        return float(self.residuals @ self.residuals)

    @property
    def residual_variance(self) -> float:
        """``SSR / dof`` (NaN when there is no degree of freedom)."""
        return self.ssr / self.dof if self.dof > 0 else float("nan")

    def covariance(self, labels=None, *, s2: float | None = None, meat=None,
                   cond_limit: float | None = None) -> Covariance:
        """:func:`covariance` of the free parameters (``labels`` of the free ones, in
        order); ``s2`` defaults to :attr:`residual_variance`."""
        return covariance(self.jacobian, labels=labels, meat=meat, cond_limit=cond_limit,
                          s2=self.residual_variance if s2 is None else s2)


@dataclass(frozen=True)
class StoppedSolve(Failure):
    """A solve that did not converge (its evaluation limit reached, or a residual not
    finite): falsy, with the ``reason``; ``last`` the :class:`Solution` where it stopped;
    ``on_limit`` True when it stopped on its evaluation limit (``max_nfev``), False when it
    failed."""

    reason: str
    last: Solution
    on_limit: bool = False


def solve(residual, x0, *, jac=None, free=None, loss: str = "linear", f_scale: float = 1.0,
          bounds=None, x_scale=None, max_nfev: int | None = None, method: str | None = None,
          xtol: float = 1e-14, ftol: float = 1e-14, gtol: float = 1e-8,
          tr_solver: str | None = None) -> Solution | StoppedSolve:
    """Least squares of ``residual(x)`` (M,) over the entries of ``x0`` (P,) that ``free``
    (P,) bool marks (all by default). ``jac(x)`` (M, P) dense or sparse, all columns (only
    the free ones are used); None: forward differences. ``loss``, ``f_scale``: a robust loss
    (scipy's names: ``soft_l1``, ``huber``, ...). ``bounds`` ((P,), (P,)) and ``x_scale``
    (P,) or ``"jac"`` over the full vector. ``method``: scipy's; by default ``lm`` for a
    plain problem, else ``trf``; a sparse Jacobian takes ``tr_solver="lsmr"``. Returns a
    :class:`Solution`, or a :class:`StoppedSolve` when it stopped on ``max_nfev`` or the
    residual is not finite."""
    x0 = np.asarray(x0, float)
    P = len(x0)
    free = np.ones(P, bool) if free is None else np.asarray(free, bool)
    if free.shape != (P,):
        raise VisionCalError(f"a mask of {free.shape} for {P} parameters")
    idx = np.flatnonzero(free)
    every = len(idx) == P

    def full(z):
        if every:
            return z
        x = x0.copy()
        x[idx] = z
        return x

    fun = residual if every else (lambda z: residual(full(z)))
    jfun = jac
    if jac is not None and not every:
        def jfun(z):
            J = jac(full(z))
            return J.tocsc()[:, idx] if sparse.issparse(J) else np.asarray(J)[:, idx]
    kw = dict(xtol=xtol, ftol=ftol, gtol=gtol, loss=loss, f_scale=f_scale)
    if method is None:
        method = "lm" if loss == "linear" and bounds is None and tr_solver is None else "trf"
    kw["method"] = method
    if bounds is not None:
        kw["bounds"] = (np.asarray(bounds[0], float)[idx], np.asarray(bounds[1], float)[idx])
    if x_scale is not None:
        kw["x_scale"] = x_scale if isinstance(x_scale, str) else np.asarray(x_scale, float)[idx]
    if max_nfev is not None:
        kw["max_nfev"] = max_nfev
    if tr_solver is not None:
        kw["tr_solver"] = tr_solver
    sol = least_squares(fun, x0[idx], jac=jfun if jfun is not None else "2-point", **kw)
    r = np.asarray(sol.fun, float)
    out = Solution(np.array(full(sol.x), float), free, r, sol.jac,
                   float(0.5 * r @ r), int(sol.nfev), str(sol.message))
    if sol.status == 0:
        return StoppedSolve(f"the least squares stopped after {sol.nfev} evaluations without "
                            f"converging (cost {out.cost:.6g})", out, on_limit=True)
    if sol.status < 0 or not np.all(np.isfinite(r)) or not np.all(np.isfinite(sol.x)):
        return StoppedSolve(f"the least squares failed: {sol.message}", out)
    return out

