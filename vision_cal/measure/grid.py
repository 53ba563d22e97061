"""Marks in the paper's own coordinates: the printed grid around a dot as its reference.

A sheet that is not flat raises the ink and the printed grid around it together; the
marker mapping (a plane through the markers) then puts both in the wrong place by the
same parallax, about ``z r / H``. The grid lines near a dot are on the paper, at
``origin + k * pitch`` (``sheet.grid``), so measuring the dot against them undoes that.

:func:`grid_offset` works on a dot's raw patch, resampled on a fine grid in sheet mm
through the global mapping (as the dot's centre is, :func:`vision_cal.measure.dots.refine_dot`):

- the background is separable in log intensity, ``log S = a(x) + b(y)``: robust medians
  over the samples away from the dot and off bare paper (quiet zones, outside the printed
  grid). ``a`` holds the lines of constant x, ``b`` those of constant y.
- The printed lines repeat with the pitch p, so the phase of the profile's component at
  1/p (a Hann-weighted Fourier sum over the window) says where they are: lines seen at
  ``origin + k p + d``. The global mapping only tells which line is which (``|d| < p/2``).
- The dot's paper coordinates are its mapped position minus ``d``: the raised grid and the
  raised dot share their shift (it varies over tens of mm, the window is a few mm), and the
  marker mapping's own error cancels too.

``d`` per dot is the local-versus-global difference: a height map in itself
(``d ~ z (p - C) / H``).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.interpolate import RectBivariateSpline

from vision_cal.config import DEFAULT, DotConfig, GridConfig
from vision_cal.dataset.photos import channel_sum
from vision_cal.dataset.session import SheetGrid
from vision_cal.measure.mapping import SheetMapping, apply_h



@dataclass(frozen=True)
class GridOffset:
    """Where the printed lines near a dot are seen, relative to where the mapping puts them:
    ``d_mm`` (2,) (x lines, y lines) and its covariance ``cov_mm2`` (2, 2); ``snr`` (2,)
    the lines' Fourier amplitude over its noise."""

    d_mm: np.ndarray
    cov_mm2: np.ndarray
    snr: np.ndarray


def _phase(profile: np.ndarray, coord: np.ndarray, ok: np.ndarray, sigma: np.ndarray,
           pitch: float, origin: float, corr_len: float, min_periods: float):
    """Line offset d (mm), its std and snr of a 1-D log profile with dark lines at
    origin + k pitch + d. ``sigma`` (n,): noise of each profile sample; ``corr_len``: the
    correlation length of neighbouring samples (a pixel on the sheet); ``min_periods``
    pitches of usable profile at least (config ``grid.min_periods``)."""
    x, a, sg = coord[ok], profile[ok], sigma[ok]
    if len(x) < 8 or np.ptp(x) < min_periods * pitch:
        return None
    # Hann taper over the usable span, mean and linear trend removed (shading)
    t = (x - x.min()) / max(np.ptp(x), 1e-9)
    w = 0.5 - 0.5 * np.cos(2 * np.pi * t)
    A = np.column_stack([np.ones_like(x), x - x.mean()])
    coef, *_ = np.linalg.lstsq(A * w[:, None], a * w, rcond=None)
    r = a - A @ coef
    c = np.sum(w * r * np.exp(-2j * np.pi * (x - origin) / pitch))
    dx = float(np.median(np.diff(x))) if len(x) > 1 else 1.0
    noise = np.sqrt(0.5 * np.sum((w * sg) ** 2) * max(corr_len / max(dx, 1e-9), 1.0))
    amp = abs(c)
    if amp <= 0:
        return None
    d = -np.angle(-c) * pitch / (2 * np.pi)   # dark lines: -c has the lines' phase
    sd = pitch / (2 * np.pi) * noise / amp
    return float(d), float(sd), float(amp / max(noise, 1e-12))


def nanmedian_columns(A: np.ndarray) -> np.ndarray:
    """Median of each column of A ignoring NaNs (NaN for an empty column); sorts once."""
    n = np.sum(np.isfinite(A), axis=0)
    srt = np.sort(A, axis=0)                      # NaNs go last
    lo = np.clip((n - 1) // 2, 0, None)
    hi = np.clip(n // 2, 0, None)
    cols = np.arange(A.shape[1])
    med = 0.5 * (srt[lo, cols] + srt[hi, cols])
    return np.where(n > 0, med, np.nan)


def _bicubic(Z: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Z (m, m) sampled at integer lattice points, evaluated at (f[j], f[i]) for all i, j."""
    k = np.arange(Z.shape[0], dtype=float)
    return RectBivariateSpline(k, k, Z, kx=3, ky=3, s=0)(f, f)


def _lens_map(mapping, c, g, half_mm, origin_px):
    """Patch coordinates of the window samples through lens + homography: exact on a 1 mm
    lattice, bicubic in between (the mapping is smooth over the window)."""
    nc = int(np.ceil(half_mm)) + 1
    gc = np.arange(-nc, nc + 1, dtype=float)
    Xc, Yc = np.meshgrid(c[0] + gc, c[1] + gc)
    uvc = mapping.sheet_to_image(np.column_stack([Xc.ravel(), Yc.ravel()])).reshape(
        Xc.shape + (2,))
    fx = (g + nc) / 1.0          # window samples in lattice units
    mx = _bicubic(uvc[..., 0] - origin_px[0], fx).astype(np.float32)
    my = _bicubic(uvc[..., 1] - origin_px[1], fx).astype(np.float32)
    return mx, my


def grid_offset(patch_rgb: np.ndarray, origin_px, mapping: SheetMapping, centre_mm,
                grid: SheetGrid, *, exclude_r_mm: float, blank_rects=None,
                dot_dia_mm: float | None = None,
                half_mm: float | None = None, step_mm: float | None = None,
                dots: DotConfig | None = None, config: GridConfig | None = None
                ) -> GridOffset | None:
    """The printed grid's offset around a dot (see the module docstring), or None when the
    lines cannot be seen well enough (too few in the patch, too faint). ``dots``: what a pen
    dot is (size, aspect; default ``vision_cal.config.DEFAULT.dots``): other dark ink is
    print. ``config``: the window and the thresholds (default ``DEFAULT.grid``; ``half_mm``
    and ``step_mm`` None: its window)."""
    dot_cfg = dots or DEFAULT.dots
    cfg = config or DEFAULT.grid
    half_mm = cfg.window_half_mm if half_mm is None else half_mm
    step_mm = cfg.window_step_mm if step_mm is None else step_mm
    S = np.asarray(patch_rgb)
    S = channel_sum(S) if S.ndim == 3 else S.astype(np.float32)
    c = np.asarray(centre_mm, float).reshape(2)
    n = int(np.ceil(half_mm / step_mm))
    g = step_mm * np.arange(-n, n + 1)
    X, Y = np.meshgrid(c[0] + g, c[1] + g)
    # the mapping (lens + homography) is smooth over the window: exact on a 1 mm lattice,
    # bicubic in between (off by far less than 1e-3 px)
    if mapping.K is None or not np.any(mapping.dist):   # a plane homography: exact, cheap
        uv = apply_h(mapping.H_img_sheet, np.column_stack([X.ravel(), Y.ravel()]))
        mx = (uv[:, 0] - origin_px[0]).reshape(X.shape).astype(np.float32)
        my = (uv[:, 1] - origin_px[1]).reshape(X.shape).astype(np.float32)
    else:
        mx, my = _lens_map(mapping, c, g, half_mm, origin_px)
    Sg = cv2.remap(S, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                   borderValue=-1.0)
    # only samples whose 2 x 2 interpolation footprint is inside the patch
    h, w = S.shape
    ok = (mx >= 0) & (my >= 0) & (mx <= w - 1) & (my <= h - 1) & (Sg > 0)
    ok &= np.hypot(X - c[0], Y - c[1]) > exclude_r_mm
    for x0, y0, x1, y1 in (() if blank_rects is None else blank_rects):
        ok &= ~((X >= x0) & (X <= x1) & (Y >= y0) & (Y <= y1))
    if grid.extent_mm is not None:
        gx0, gy0, gx1, gy1 = grid.extent_mm
        ok &= (X >= gx0) & (X <= gx1) & (Y >= gy0) & (Y <= gy1)
    if ok.sum() < 50:
        return None
    # not the printed grid: other ink, the arm, shadows, anything far darker than the
    # paper (the lines darken it by a few per cent), with a margin of half a millimetre
    paper = float(np.percentile(Sg[ok], 90))
    dark = ~(Sg > cfg.dark_fraction * paper)
    if dark.any():
        # dark ink that is no pen dot (larger than one, or elongated: a bar, an axis, a
        # label) away from this dot: printed content the grid does not hold, whose edges
        # the lines' phase would take for grid; the grid is no reference here
        dia = float(dot_dia_mm or dot_cfg.default_diameter_mm)
        n, _, st, _ = cv2.connectedComponentsWithStats((dark & ok).astype(np.uint8),
                                                       connectivity=8)
        for j in range(1, n):
            area_mm2 = st[j, cv2.CC_STAT_AREA] * step_mm * step_mm
            long_mm = max(st[j, cv2.CC_STAT_WIDTH], st[j, cv2.CC_STAT_HEIGHT]) * step_mm
            if area_mm2 > dot_cfg.max_area_ratio * np.pi * (0.5 * dia) ** 2 or \
                    long_mm > dot_cfg.max_aspect * dia:
                return None
        k = 2 * int(np.ceil(0.5 / step_mm)) + 1
        dark = cv2.dilate(dark.astype(np.uint8), np.ones((k, k), np.uint8)) > 0
        ok &= ~dark
    if ok.sum() < 50:
        return None
    L = np.where(ok, np.log(np.maximum(Sg, 1.0)), np.nan)
    a = np.zeros(X.shape[1])
    b = np.zeros(X.shape[0])
    for _ in range(2):
        a = nanmedian_columns(L - b[:, None])
        b = nanmedian_columns((L - a[None, :]).T)
    # a column (row) counts when enough of its samples were usable
    col_ok = np.isfinite(a) & (ok.sum(axis=0) >= 0.25 * ok.shape[0])
    row_ok = np.isfinite(b) & (ok.sum(axis=1) >= 0.25 * ok.shape[1])
    mm_px = float(mapping.mm_per_px(c)[0])
    # noise of each median: the robust scatter of the samples about the separable model,
    # over the number of independent samples (a pixel holds (mm_px / step)^2 of them)
    res = (L - a[None, :] - b[:, None])[ok]
    s_L = 1.4826 * float(np.median(np.abs(res - np.median(res))))
    per_px = max((mm_px / step_mm) ** 2, 1.0)
    n_col = np.maximum(ok.sum(axis=0) / np.sqrt(per_px), 1.0)   # along a column: 1-D
    n_row = np.maximum(ok.sum(axis=1) / np.sqrt(per_px), 1.0)
    sig_a, sig_b = 1.25 * s_L / np.sqrt(n_col), 1.25 * s_L / np.sqrt(n_row)
    px = _phase(np.nan_to_num(a), X[0], col_ok, sig_a, grid.pitch_mm, grid.origin_mm[0], mm_px,
                cfg.min_periods)
    py = _phase(np.nan_to_num(b), Y[:, 0], row_ok, sig_b, grid.pitch_mm, grid.origin_mm[1],
                mm_px, cfg.min_periods)
    if px is None or py is None or min(px[2], py[2]) < cfg.min_contrast:
        return None
    return GridOffset(np.array([px[0], py[0]]), np.diag([px[1] ** 2, py[1] ** 2]),
                      np.array([px[2], py[2]]))
