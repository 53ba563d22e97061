"""A printed grid that is not where ``sheet.grid`` declares it (issue 18).

The markers and the printed grid are two references. Around every dot the grid's offset
from where the marker mapping puts its declared lines is measured
(:func:`vision_cal.measure.grid.grid_offset`). A raised or curled paper moves the lines
differently at each place and from each camera place (parallax); a grid printed elsewhere
than declared (another program's sheet, a hand-edited ``origin_mm``) moves them by the same
amount everywhere, in every photo. The two are told apart by what they are (issue 28):

- the offsets, taken modulo the pitch (the phase of the lines is all a window sees), agree
  over the dots (mean resultant length of the phase above ``min_agreement``) and their mean
  is beyond ``min_offset_mm`` and ``min_offset_sigmas`` standard errors, counted over the
  *sites* (a mark seen from one camera place: a series repeats every mark from a fixed
  camera, its photos are not independent evidence); and
- the constant is what they are: a height per mark along its parallax direction
  ``v = (p - C_xy) / C_z`` (:func:`vision_cal.measure.height.camera_centre_mm`), added to the
  constant, does not explain them significantly better (F test at ``alpha``, free of the
  noise's scale). A paper raised under a tilted camera moves every grid line along its
  own ``v`` by its own height: offsets that agree in sign over the sheet (-0.067 mm in x on
  the bumped sheet of ``renders/bumped_tilted.yaml``), but a field that follows the
  parallax, not a constant. Photos without a camera pose (no lens) are judged by the
  constant's own chi-square (its residual no larger than the offsets' noise).

Then the declaration is wrong: the run says so in one line naming ``sheet.grid.origin_mm``
and measures against the markers. The thresholds are config ``grid_declaration``
(:class:`vision_cal.config.GridDeclarationConfig`); the offsets' noise floor and what one
camera place is are config ``sheet_height``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from vision_cal.config import DEFAULT, GridDeclarationConfig, SheetHeightConfig
from vision_cal.errors import VisionCalError
from vision_cal.measure.height import camera_centre_mm, place_of


@dataclass(frozen=True)
class GridMisdeclared:
    """The constant offset seen (x lines, y lines; mm, within +-pitch/2) and its message."""

    offset_mm: np.ndarray
    n_dots: int
    message: str


@dataclass(frozen=True)
class _Site:
    """One mark seen from one camera place: its photos' mean offset, its weight (inverse
    covariance), its parallax direction (None: no camera pose) and which mark it is."""

    d: np.ndarray
    W: np.ndarray
    v: np.ndarray | None
    mark: int


def _centre(im):
    K, mapping = getattr(im, "K", None), getattr(im, "mapping", None)
    if K is None or mapping is None:
        return None
    try:
        return camera_centre_mm(mapping.H_img_sheet, K)
    except (VisionCalError, np.linalg.LinAlgError):
        return None


def _sites(images, mean, p, cfg: GridDeclarationConfig, hc: SheetHeightConfig) -> list[_Site]:
    """The dots' offsets (unwrapped about the circular ``mean``) grouped by mark (dots
    within ``same_mark_mm``) and camera place (centres within ``same_place_fraction`` of
    their height; photos without a pose share one place)."""
    marks: list[np.ndarray] = []
    places: list[np.ndarray] = []
    groups: dict = {}
    for im in images:
        if im.status != "ok":
            continue
        off = np.asarray(getattr(im, "dots_grid_offset_mm", ()), float).reshape(-1, 2)
        if not len(off):
            continue
        xy = np.asarray(im.dots_xy_mm, float).reshape(-1, 2)
        cov = np.asarray(getattr(im, "dots_grid_offset_cov_mm2", ()), float).reshape(-1, 2, 2)
        C = _centre(im)
        k = -1 if C is None else place_of(places, C, hc.same_place_fraction)
        for j in range(len(off)):
            if not np.all(np.isfinite(off[j])):
                continue
            d = mean + (off[j] - mean + p / 2) % p - p / 2
            m = next((i for i, q in enumerate(marks)
                      if np.linalg.norm(xy[j] - q) < cfg.same_mark_mm), None)
            if m is None:
                marks.append(xy[j])
                m = len(marks) - 1
            c = cov[j] if j < len(cov) and np.all(np.isfinite(cov[j])) else np.zeros((2, 2))
            W = np.linalg.inv(c + np.eye(2) * hc.offset_floor_mm**2)
            v = None if C is None else (xy[j] - C[:2]) / C[2]
            groups.setdefault((m, k), []).append((W, d, v))
    out = []
    for (m, k), g in groups.items():
        Ws = sum(W for W, _, _ in g)
        d = np.linalg.solve(Ws, sum(W @ dd for W, dd, _ in g))
        # photos from one place share their pixel phase: the mean is no better than one
        W1 = Ws / len(g)
        v = None if k < 0 else np.mean([vv for _, _, vv in g], axis=0)
        out.append(_Site(d, W1, v, m))
    return out


def _chi2(rows_A, y) -> tuple[float, int]:
    sol, *_ = np.linalg.lstsq(rows_A, y, rcond=None)
    return float(np.sum((y - rows_A @ sol) ** 2)), int(len(y) - np.linalg.matrix_rank(rows_A))


def _follows_parallax(sites: list[_Site], alpha: float) -> bool:
    """Whether heights per mark along ``v`` explain the offsets better than the constant
    alone (F test; without poses: the constant's chi-square significant)."""
    n = len(sites)
    marks = sorted({s.mark for s in sites})
    col = {m: i for i, m in enumerate(marks)}
    y = np.zeros(2 * n)
    A = np.zeros((2 * n, 2))
    Z = np.zeros((2 * n, len(marks)))
    for r, s in enumerate(sites):
        L = np.linalg.cholesky(s.W).T
        sl = slice(2 * r, 2 * r + 2)
        y[sl] = L @ s.d
        A[sl] = L
        if s.v is not None:
            Z[sl, col[s.mark]] = L @ s.v
    c_chi2, c_dof = _chi2(A, y)
    if not np.any(Z):
        return bool(c_dof > 0 and stats.chi2.sf(c_chi2, c_dof) < alpha)
    h_chi2, h_dof = _chi2(np.hstack([A, Z]), y)
    k = c_dof - h_dof
    if k <= 0 or h_dof <= 0:
        return False
    if h_chi2 <= 0.0:
        return c_chi2 > 0.0
    F = ((c_chi2 - h_chi2) / k) / (h_chi2 / h_dof)
    return bool(stats.f.sf(F, k, h_dof) < alpha)


def misdeclared_grid(images, grid, config: GridDeclarationConfig | None = None, *,
                     height_config: SheetHeightConfig | None = None) -> GridMisdeclared | None:
    """``images``: photo results (``dots_grid_offset_mm`` (K, 2), NaN where the grid was not
    used, their covariance, the mapping and K for the camera place); ``grid``: the declared
    :class:`SheetGrid`. None when the grid is where declared, or the offsets are a field
    following the parallax (a raised paper), or it cannot tell. ``config``: the thresholds
    (default ``DEFAULT.grid_declaration``); ``height_config``: the offsets' noise floor and
    the camera places (default ``DEFAULT.sheet_height``)."""
    cfg = config or DEFAULT.grid_declaration
    hc = height_config or DEFAULT.sheet_height
    if grid is None:
        return None
    offs = [np.asarray(im.dots_grid_offset_mm, float).reshape(-1, 2) for im in images
            if im.status == "ok" and len(getattr(im, "dots_grid_offset_mm", ()))]
    d = np.concatenate(offs) if offs else np.zeros((0, 2))
    d = d[np.all(np.isfinite(d), axis=1)]
    if len(d) < cfg.min_dots:
        return None
    p = float(grid.pitch_mm)
    z = np.exp(2j * np.pi * d / p)            # (n, 2) phases of the lines
    zm = z.mean(axis=0)
    agree = np.abs(zm)
    mean = np.angle(zm) * p / (2 * np.pi)
    sites = _sites(images, mean, p, cfg, hc)
    if len(sites) < cfg.min_dots:
        return None
    # standard error of a circular mean from its scatter, over the independent sites
    spread = np.sqrt(np.maximum(-2.0 * np.log(np.maximum(agree, 1e-12)), 0.0)) * p / (2 * np.pi)
    se = spread / np.sqrt(len(sites))
    # what the offsets share and no number of dots averages: the printer's displacement the
    # grid reference carries (measure/grid_print: its prior, or what a survey left between
    # the markers; issue 37: a survey's 0.077 mm between rim markers named a misdeclared
    # grid), at most the median dot's offset variance
    cov = np.concatenate([np.asarray(getattr(im, "dots_grid_offset_cov_mm2", ()), float)
                          .reshape(-1, 2, 2) for im in images if im.status == "ok"]
                         or [np.zeros((0, 2, 2))])
    diag = np.diagonal(cov, axis1=1, axis2=2)
    diag = diag[np.all(np.isfinite(diag), axis=1)]
    if len(diag):
        se = np.sqrt(se**2 + np.median(diag, axis=0))
    off = np.where((agree >= cfg.min_agreement) & (np.abs(mean) > cfg.min_offset_mm)
                   & (np.abs(mean) > cfg.min_offset_sigmas * se), mean, 0.0)
    if not np.any(off):
        return None
    if _follows_parallax(sites, cfg.alpha):    # a raised paper: the height stage's business
        return None
    ox, oy = (float(v) for v in off)
    origin = [float(v) for v in grid.origin_mm]
    msg = (f"sheet.grid.origin_mm: the printed grid is {ox:+.3f} mm in x and {oy:+.3f} mm in "
           f"y (modulo its {p:g} mm pitch) from where {origin} puts it, the same at all "
           f"{len(d)} dots of every photo: a wrong declaration, not a height; the marks are "
           "measured against the markers (declare origin_mm "
           f"[{origin[0] + ox:.3f}, {origin[1] + oy:.3f}] or another whole pitch from it)")
    return GridMisdeclared(np.array([ox, oy]), len(d), msg)
