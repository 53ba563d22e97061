"""Sheet effects in the residual: a smooth field over the paper that no robot effect explains.

A paper that is not flat, seen through the marker mapping, moves each mark by about
``z r / H``: a residual that varies smoothly over the *sheet* (neighbouring marks agree)
whatever joints drew them. Robot effects that are not themselves smooth over the sheet
(backlash flips with the approach side, which the plan randomises) do not look like it.

:func:`smooth_residual` tests for it: each mark's residual is predicted from its
neighbours (Gaussian-weighted mean, leave-one-out) and the agreement between residuals
and predictions is compared with the same statistic after shuffling the residuals over
the marks' positions (a permutation test: no distribution assumed). Significant
agreement is reported as ``unexplained`` with the smoothed field as a map; the
calibration never fits it as ``sheet_affine``, a cyclic error or a length change.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter

from vision_cal.config import DEFAULT, SmoothResidualConfig


#: up to this many marks the kernel is exact (a dense N x N matrix, built once); above, each
#: mark is spread over the four corners of its cell on a grid of ``length_mm /
#: GRID_PER_LENGTH`` (cloud in cell), the grid is smoothed (scipy.ndimage.gaussian_filter)
#: and read back the same way, so a permutation costs O(N) plus a fixed grid. The kernel
#: differs from the exact Gaussian by about 1 % of the smoothed value; the permutation
#: test stays exact, since the observed statistic and its null use the same kernel.
EXACT_MAX_MARKS = 400
GRID_PER_LENGTH = 3
MAX_GRID_CELLS = 1_000_000


class _Smoother:
    """The leave-one-out Gaussian-weighted mean of residuals at each mark; the positions are
    fixed, so what depends on them (the kernel, its row sums) is built once and a
    permutation of the residuals costs O(N) (grid) or one N x N product (exact)."""

    def __init__(self, xy: np.ndarray, length_mm: float):
        self.n = len(xy)
        if self.n <= EXACT_MAX_MARKS:
            D2 = np.sum((xy[:, None] - xy[None]) ** 2, axis=2)
            self.W = np.exp(-D2 / (2 * length_mm**2))
            np.fill_diagonal(self.W, 0.0)
            self.s = self.W.sum(axis=1)
            self.floor = 1e-12
            return
        self.W = None
        lo = xy.min(axis=0)
        span = np.maximum(xy.max(axis=0) - lo, 1e-9)
        cell = max(length_mm / GRID_PER_LENGTH,
                   float(np.sqrt(np.prod(span + 2 * length_mm) / MAX_GRID_CELLS)))
        u = (xy - lo) / cell
        ij = np.floor(u).astype(np.int64)
        f = u - ij                                                   # (N, 2) in [0, 1)
        self.shape = tuple(int(v) + 2 for v in ij.max(axis=0))
        # the four corners of each mark's cell and their bilinear weights, (4, N) each
        corners = [(0, 0), (1, 0), (0, 1), (1, 1)]
        self.flat = np.stack([np.ravel_multi_index((ij[:, 0] + a, ij[:, 1] + b), self.shape)
                              for a, b in corners])
        self.w = np.stack([(f[:, 0] if a else 1 - f[:, 0]) * (f[:, 1] if b else 1 - f[:, 1])
                           for a, b in corners])
        self.sigma = length_mm / cell
        # the kernel between two corners (offsets -1..1), for the weight of a mark on itself
        r = int(np.ceil(4.0 * self.sigma)) + 1
        delta = np.zeros((2 * r + 1, 2 * r + 1))
        delta[r, r] = 1.0
        g = gaussian_filter(delta, self.sigma, mode="constant")
        self_w = np.zeros(self.n)
        for (a, b), wa in zip(corners, self.w):
            for (c, d), wc in zip(corners, self.w):
                self_w += wa * wc * g[r + a - c, r + b - d]
        self.self_w = self_w
        self.s = self._field(np.ones(self.n)) - self_w
        self.floor = 1e-9 * float(g[r, r])

    def _field(self, v: np.ndarray) -> np.ndarray:
        """Kernel-weighted sums of ``v`` (N,) at each mark, itself included."""
        size = int(np.prod(self.shape))
        grid = np.bincount(self.flat.ravel(), weights=(self.w * v).ravel(), minlength=size)
        sm = gaussian_filter(grid.reshape(self.shape), self.sigma, mode="constant").ravel()
        return np.sum(self.w * sm[self.flat], axis=0)

    def __call__(self, r: np.ndarray) -> np.ndarray:
        """Leave-one-out smoothed residual (N, 2) of ``r`` (N, 2)."""
        if self.W is not None:
            num = self.W @ r
        else:
            num = np.column_stack([self._field(r[:, c]) - self.self_w * r[:, c]
                                   for c in range(2)])
        s = self.s[:, None]
        return np.where(s > self.floor, num / np.maximum(s, self.floor), 0.0)


def _agreement(r, pred):
    den = np.sqrt(np.sum(r**2) * np.sum(pred**2))
    return float(np.sum(r * pred) / den) if den > 0 else 0.0


#: the likely cause of a smooth residual, by default (a sheet measured against markers only)
NOT_FLAT = ("the sheet is probably not flat (measure the marks against its printed grid: "
            "declare sheet.grid)")
#: ... and where the sheet's print was measured and the marks are against its markers
PRINT_BETWEEN = ("the print between the markers, with the lens and the paper's shape the "
                 "views cannot tell it from (calibration.json print: declare the camera's "
                 "lens, or survey the sheet)")


def smooth_residual(xy_mm, residual_mm, extent_mm, *, alpha: float | None = None,
                    length_mm: float | None = None, n_perm: int | None = None, rng=None,
                    config: SmoothResidualConfig | None = None,
                    cause: str = NOT_FLAT) -> dict | None:
    """The ``unexplained`` entry for a spatially smooth residual, or None.

    ``xy_mm`` (N, 2) mark positions, ``residual_mm`` (N, 2) after the final model;
    ``config`` the test's level, length, map step and permutations (default
    ``DEFAULT.smooth_residual``; ``alpha``, ``length_mm``, ``n_perm`` override it);
    ``cause`` what the sentence names (:data:`NOT_FLAT`, :data:`PRINT_BETWEEN`).
    """
    cfg = config or DEFAULT.smooth_residual
    alpha = cfg.alpha if alpha is None else alpha
    length_mm = cfg.length_mm if length_mm is None else length_mm
    n_perm = cfg.n_permutations if n_perm is None else n_perm
    xy = np.asarray(xy_mm, float).reshape(-1, 2)
    r = np.asarray(residual_mm, float).reshape(-1, 2)
    ok = np.all(np.isfinite(r), axis=1)
    xy, r = xy[ok], r[ok]
    if len(r) < 10:
        return None
    rng = np.random.default_rng(0 if rng is None else rng)  # a fixed seed: reproducible
    smoother = _Smoother(xy, length_mm)  # once: only the residuals are permuted
    pred = smoother(r)
    stat = _agreement(r, pred)
    null = np.empty(n_perm)
    for k in range(n_perm):
        rp = r[rng.permutation(len(r))]
        null[k] = _agreement(rp, smoother(rp))
    p = float((1 + np.sum(null >= stat)) / (n_perm + 1))
    if p >= alpha:
        return None
    x0, y0, x1, y1 = (float(v) for v in extent_mm)
    xs = np.arange(x0, x1 + 1e-9, cfg.map_step_mm)
    ys = np.arange(y0, y1 + 1e-9, cfg.map_step_mm)
    X, Y = np.meshgrid(xs, ys)
    P = np.column_stack([X.ravel(), Y.ravel()])
    field = np.full((len(P), 2), np.nan)
    for a in range(0, len(P), 16):  # 16 map points at a time: memory O(N), not O(P N)
        W = np.exp(-np.sum((P[a:a + 16, None] - xy[None]) ** 2, axis=2) / (2 * length_mm**2))
        s = W.sum(axis=1, keepdims=True)
        field[a:a + 16] = np.where(s > 0.5, (W @ r) / np.maximum(s, 1e-12), np.nan)
    rms = float(np.sqrt(np.mean(np.sum(pred**2, axis=1))))
    return {"seen": [f"a residual that varies smoothly over the sheet (neighbouring marks "
                     f"agree, permutation p = {p:.2g}, smooth part {1000 * rms:.1f} um RMS) "
                     f"that no robot effect explains: {cause}"],
            "kind": "sheet",
            "map": {"x_mm": xs.tolist(), "y_mm": ys.tolist(),
                    "dx_mm": np.round(field[:, 0].reshape(X.shape), 5).tolist(),
                    "dy_mm": np.round(field[:, 1].reshape(X.shape), 5).tolist(),
                    "length_mm": length_mm},
            "p_value": p, "smooth_rms_mm": rms}
