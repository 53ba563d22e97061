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

LENGTH_MM = 60.0
MAP_STEP_MM = 40.0


def _loo_smooth(xy, r, length_mm):
    D2 = np.sum((xy[:, None] - xy[None]) ** 2, axis=2)
    W = np.exp(-D2 / (2 * length_mm**2))
    np.fill_diagonal(W, 0.0)
    s = W.sum(axis=1, keepdims=True)
    return (W @ r) / np.maximum(s, 1e-12), s.ravel()


def _agreement(r, pred):
    den = np.sqrt(np.sum(r**2) * np.sum(pred**2))
    return float(np.sum(r * pred) / den) if den > 0 else 0.0


def smooth_residual(xy_mm, residual_mm, extent_mm, *, alpha: float = 1e-3,
                    length_mm: float = LENGTH_MM, n_perm: int = 1999, rng=None) -> dict | None:
    """The ``unexplained`` entry for a spatially smooth residual, or None.

    ``xy_mm`` (N, 2) mark positions, ``residual_mm`` (N, 2) after the final model.
    """
    xy = np.asarray(xy_mm, float).reshape(-1, 2)
    r = np.asarray(residual_mm, float).reshape(-1, 2)
    ok = np.all(np.isfinite(r), axis=1)
    xy, r = xy[ok], r[ok]
    if len(r) < 10:
        return None
    rng = np.random.default_rng(0 if rng is None else rng)  # a fixed seed: reproducible
    pred, _ = _loo_smooth(xy, r, length_mm)
    stat = _agreement(r, pred)
    null = np.empty(n_perm)
    for k in range(n_perm):
        rp = r[rng.permutation(len(r))]
        null[k] = _agreement(rp, _loo_smooth(xy, rp, length_mm)[0])
    p = float((1 + np.sum(null >= stat)) / (n_perm + 1))
    if p >= alpha:
        return None
    x0, y0, x1, y1 = (float(v) for v in extent_mm)
    xs = np.arange(x0, x1 + 1e-9, MAP_STEP_MM)
    ys = np.arange(y0, y1 + 1e-9, MAP_STEP_MM)
    X, Y = np.meshgrid(xs, ys)
    P = np.column_stack([X.ravel(), Y.ravel()])
    W = np.exp(-np.sum((P[:, None] - xy[None]) ** 2, axis=2) / (2 * length_mm**2))
    s = W.sum(axis=1, keepdims=True)
    field = np.where(s > 0.5, (W @ r) / np.maximum(s, 1e-12), np.nan)
    rms = float(np.sqrt(np.mean(np.sum(pred**2, axis=1))))
    return {"seen": [f"a residual that varies smoothly over the sheet (neighbouring marks "
                     f"agree, permutation p = {p:.2g}, smooth part {1000 * rms:.1f} um RMS) "
                     "that no robot effect explains: the sheet is probably not flat (measure "
                     "the marks against its printed grid: declare sheet.grid)"],
            "kind": "sheet",
            "map": {"x_mm": xs.tolist(), "y_mm": ys.tolist(),
                    "dx_mm": np.round(field[:, 0].reshape(X.shape), 5).tolist(),
                    "dy_mm": np.round(field[:, 1].reshape(X.shape), 5).tolist(),
                    "length_mm": length_mm},
            "p_value": p, "smooth_rms_mm": rms}
