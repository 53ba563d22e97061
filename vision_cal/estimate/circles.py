"""Circle fits: the seed paper's three-point circles, generalised.

Marks that share a joint-2 angle lie on a circle about the base (joint-1 axis); marks
that share a joint-1 angle lie on a circle about the elbow (joint-2 axis).

:meth:`Circle.from_three_points` is the paper's construction (its eqs 1-9: the
circumcircle). :meth:`Circle.from_estimate` fits any number of points with the *Hyper*
algebraic fit (Al-Sharadqah and Chernov 2009; unbiased to second order, unlike Kasa's
fit, which pulls short arcs towards small radii), refined by the geometric (orthogonal
distance) fit (:func:`vision_cal.model.solve.solve`), with the covariance of (cx, cy, r)
by the one policy (:func:`vision_cal.model.solve.covariance`, ``s^2 = SSR / dof``).

Arc span limits a circle fit: over an arc of span ``s`` (rad) the centre's uncertainty
along the arc's bisector grows roughly like ``sigma / (1 - cos(s/2))``, so the paper's
+-20 deg arc (s = 40 deg) amplifies the mark noise about 16x in the base position.

Points that no circle fits (fewer than three, collinear, coincident) give a
:class:`vision_cal.model.lsq.FailedFit`, falsy, with the reason (as
``skimage.measure.CircleModel.from_estimate`` gives a ``FailedEstimation``): a caller that
branches tests ``if not circle``, one that cannot go on calls ``.or_raise()``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import eig

from vision_cal.model.lsq import FailedFit
from vision_cal.model.rms import rms
from vision_cal.model.solve import solve


@dataclass(frozen=True)
class Circle:
    """A fitted circle in sheet mm. ``cov`` is the (3, 3) covariance of (cx, cy, r) (its
    diagonal inf for what the points do not fix)."""

    center_mm: tuple[float, float]
    radius_mm: float
    cov: np.ndarray | None = None
    arc_span_deg: float = float("nan")
    rms_mm: float = float("nan")
    n_points: int = 0

    @property
    def std(self) -> np.ndarray:
        """One standard deviation of (cx, cy, r), mm (NaN where unknown)."""
        if self.cov is None:
            return np.full(3, np.nan)
        return np.sqrt(np.clip(np.diag(self.cov), 0.0, None))

    @classmethod
    def from_three_points(cls, xy_mm) -> "Circle | FailedFit":
        """The circumcircle of three points (the paper's eqs 1-9); a :class:`FailedFit`
        when there is none."""
        p = np.asarray(xy_mm, dtype=float)
        if p.shape != (3, 2):
            return FailedFit(f"a three-point circle needs 3 points, got {p.shape[0]}")
        (x1, y1), (x2, y2), (x3, y3) = p
        d = 2.0 * (x1 * (y2 - y3) + x2 * (y3 - y1) + x3 * (y1 - y2))
        scale = np.ptp(p, axis=0).max() ** 2
        if abs(d) < 1e-12 * max(scale, 1e-300):
            return FailedFit("the three points are collinear: no circle passes through them")
        s1, s2, s3 = x1**2 + y1**2, x2**2 + y2**2, x3**2 + y3**2
        cx = (s1 * (y2 - y3) + s2 * (y3 - y1) + s3 * (y1 - y2)) / d
        cy = (s1 * (x3 - x2) + s2 * (x1 - x3) + s3 * (x2 - x1)) / d
        r = float(np.hypot(x1 - cx, y1 - cy))
        return cls((float(cx), float(cy)), r, None, arc_span_deg(p, (cx, cy)), 0.0, 3)

    @classmethod
    def from_estimate(cls, xy_mm, *, refine: bool = True) -> "Circle | FailedFit":
        """Hyper algebraic fit, then (``refine``) the geometric fit with covariance; a
        :class:`FailedFit` when no circle fits the points."""
        p = np.asarray(xy_mm, dtype=float)
        if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3:
            return FailedFit(f"a circle fit needs at least 3 points, got {len(p)}")
        if len(p) == 3:
            return cls.from_three_points(p)
        h = _hyper(p)
        if not h:
            return h
        cx, cy, r = h
        if not refine:
            return cls((cx, cy), r, None, arc_span_deg(p, (cx, cy)), rms(_dist(p, (cx, cy, r))), len(p))
        sol = solve(lambda v: _dist(p, v), np.array([cx, cy, r]),
                    jac=lambda v: _dist_jac(p, v), xtol=1e-15, ftol=1e-15)
        if not sol:
            return FailedFit(f"the circle's geometric fit: {sol.reason}")
        v = sol.x
        res = _dist(p, v)
        # the one policy (s^2 = SSR / dof): what the arc cannot fix has an infinite variance
        cov = sol.covariance(("cx", "cy", "r")).stated if sol.dof > 0 else None
        return cls((float(v[0]), float(v[1])), float(abs(v[2])), cov,
                   arc_span_deg(p, v[:2]), rms(res), len(p))

    def or_raise(self) -> "Circle":
        """This circle (the twin of :meth:`FailedFit.or_raise`)."""
        return self

    def residuals(self, xy_mm) -> np.ndarray:
        """Signed distance (N,) of each point from the circle, mm."""
        return _dist(np.asarray(xy_mm, dtype=float), (*self.center_mm, self.radius_mm))

    def predict(self, angle_rad) -> np.ndarray:
        """Points (N, 2) on the circle at polar angles ``angle_rad`` about the centre."""
        a = np.asarray(angle_rad, dtype=float)
        return np.stack([self.center_mm[0] + self.radius_mm * np.cos(a),
                         self.center_mm[1] + self.radius_mm * np.sin(a)], axis=-1)

    def to_json(self) -> dict:
        return {"center_mm": list(self.center_mm), "radius_mm": self.radius_mm,
                "std_mm": [float(x) for x in self.std], "arc_span_deg": self.arc_span_deg,
                "rms_mm": self.rms_mm, "n_points": self.n_points}


def arc_span_deg(xy_mm, center) -> float:
    """Angular span of the points about ``center``: 360 deg minus the largest gap."""
    p = np.asarray(xy_mm, dtype=float)
    a = np.sort(np.arctan2(p[:, 1] - center[1], p[:, 0] - center[0]))
    gaps = np.diff(np.concatenate([a, [a[0] + 2 * np.pi]]))
    return float(np.degrees(2 * np.pi - gaps.max()))


def _dist(p, v):
    return np.hypot(p[:, 0] - v[0], p[:, 1] - v[1]) - v[2]


def _dist_jac(p, v):
    d = np.hypot(p[:, 0] - v[0], p[:, 1] - v[1])
    d = np.where(d > 0, d, 1e-300)
    return np.stack([-(p[:, 0] - v[0]) / d, -(p[:, 1] - v[1]) / d, -np.ones(len(p))], axis=1)


def _hyper(p: np.ndarray) -> tuple[float, float, float] | FailedFit:
    """Hyper fit (Al-Sharadqah & Chernov 2009) on centred, scaled data: (cx, cy, r)."""
    m = p.mean(axis=0)
    q = p - m
    s = np.sqrt(np.mean(np.sum(q**2, axis=1)))
    if s == 0:
        return FailedFit("all points coincide: no circle can be fitted")
    q = q / s
    z = np.sum(q**2, axis=1)
    Z = np.stack([z, q[:, 0], q[:, 1], np.ones(len(q))], axis=1)
    M = Z.T @ Z / len(q)
    zm = z.mean()
    H = np.array([[8 * zm, 0, 0, 2], [0, 1, 0, 0], [0, 0, 1, 0], [2, 0, 0, 0]], dtype=float)
    w, V = eig(M, H)
    w = np.real(w)
    ok = np.isfinite(w) & (w > -1e-12)
    if not ok.any():
        return FailedFit("the circle fit found no solution (points nearly collinear?)")
    k = np.flatnonzero(ok)[np.argmin(w[ok])]
    A, B, C, D = np.real(V[:, k])
    if abs(A) < 1e-14:
        return FailedFit("the points are collinear: no circle fits them")
    cx, cy = -B / (2 * A), -C / (2 * A)
    r = np.sqrt(max(B * B + C * C - 4 * A * D, 0.0)) / (2 * abs(A))
    return float(cx * s + m[0]), float(cy * s + m[1]), float(r * s)
