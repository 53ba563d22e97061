"""A printed grid that is not where ``sheet.grid`` declares it (issue 18).

The markers and the printed grid are two references. Around every dot the grid's offset
from where the marker mapping puts its declared lines is measured
(:func:`vision_cal.measure.grid.grid_offset`). A raised or curled paper moves the lines
differently at each place and from each camera place (parallax); a grid printed elsewhere
than declared (another program's sheet, a hand-edited ``origin_mm``) moves them by the same
amount everywhere, in every photo. When the offsets, taken modulo the pitch (the phase of
the lines is all a window sees), agree over the dots (mean resultant length of the phase
above ``min_agreement``) and their mean is beyond ``min_offset_mm`` and
``min_offset_sigmas`` standard errors, the declaration is wrong: the run says so in one
line naming ``sheet.grid.origin_mm`` and measures against the markers. The thresholds are
config ``grid_declaration`` (:class:`vision_cal.config.GridDeclarationConfig`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision_cal.config import DEFAULT, GridDeclarationConfig


@dataclass(frozen=True)
class GridMisdeclared:
    """The constant offset seen (x lines, y lines; mm, within +-pitch/2) and its message."""

    offset_mm: np.ndarray
    n_dots: int
    message: str


def misdeclared_grid(images, grid, config: GridDeclarationConfig | None = None
                     ) -> GridMisdeclared | None:
    """``images``: photo results (``dots_grid_offset_mm`` (K, 2), NaN where the grid was not
    used); ``grid``: the declared :class:`SheetGrid`. None when the grid is where declared
    (or cannot tell). ``config``: the thresholds (default ``DEFAULT.grid_declaration``)."""
    cfg = config or DEFAULT.grid_declaration
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
    # standard error of a circular mean from its scatter
    spread = np.sqrt(np.maximum(-2.0 * np.log(np.maximum(agree, 1e-12)), 0.0)) * p / (2 * np.pi)
    se = spread / np.sqrt(len(d))
    off = np.where((agree >= cfg.min_agreement) & (np.abs(mean) > cfg.min_offset_mm)
                   & (np.abs(mean) > cfg.min_offset_sigmas * se), mean, 0.0)
    if not np.any(off):
        return None
    ox, oy = (float(v) for v in off)
    origin = [float(v) for v in grid.origin_mm]
    msg = (f"sheet.grid.origin_mm: the printed grid is {ox:+.3f} mm in x and {oy:+.3f} mm in "
           f"y (modulo its {p:g} mm pitch) from where {origin} puts it, the same at all "
           f"{len(d)} dots of every photo: a wrong declaration, not a height; the marks are "
           "measured against the markers (declare origin_mm "
           f"[{origin[0] + ox:.3f}, {origin[1] + oy:.3f}] or another whole pitch from it)")
    return GridMisdeclared(np.array([ox, oy]), len(d), msg)
