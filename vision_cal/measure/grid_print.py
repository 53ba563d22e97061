"""Where the printer put the grid lines: the print's displacement at a dot (issue 37).

The printed grid is a reference only as good as the printer: its lines are at
``origin + k * pitch + D(p)``, ``D`` the printer's smooth displacement of the ink, so a dot
measured against them (:mod:`vision_cal.measure.grid`) is off by ``-D(p)`` (README's
rehearsal, a print 0.15 mm RMS off: marks 0.18 mm from the pen, and ``D`` read as 2.5 mm of
paper height). The markers are displaced by the same field; where they were measured as
printed (a survey, or photos from several places: :mod:`vision_cal.measure.asprinted`) the
field is known at each marker, in the frame and gauge the marker mapping uses.

:class:`GridPrint` is ``D`` at any sheet point with its covariance:

- **measured**: a Gaussian process through the markers' displacement (each marker's mean
  corner deviation: its growth cancels between opposite corners), each marker's own std
  as noise, a squared-exponential kernel shared by the two components, its lengths along
  x and along y apart (a feed wave is the same across the page) and its amplitude by
  maximum marginal likelihood over config ``grid.print_length_min_mm`` .. ``_max_mm``
  and multiples of the unmeasured print's std (up to ``grid.print_amplitude_max``):
  between markers far apart it knows the field only as well as the markers say, and its
  std says so.
- **not measured** (:meth:`GridPrint.unmeasured`): ``D = 0`` with the printer's prior
  (config ``uncertainty.unmeasured_print_mm``, 2-D RMS) per axis: a grid offset is then
  never read as a height, nor the grid preferred to the markers, by more than it can know.

:mod:`vision_cal.measure.finish` subtracts ``D`` from each dot's grid offset and adds its
covariance to the dot's and to the offset's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision_cal.config import DEFAULT, EstimatorConfig


@dataclass(frozen=True)
class GridPrint:
    """The print's displacement at sheet points (module docstring). ``xy_mm`` (n, 2) where
    it was measured (none: the prior alone), ``alpha`` (n, 2) the process's weights per
    axis, ``K_inv`` (n, n) its inverse kernel matrix (noise included), ``length_mm`` and
    ``amplitude_mm`` (per axis std far from every marker), ``measured``; ``length_mm`` (2,)
    the kernel's length along x and along y."""

    xy_mm: np.ndarray
    alpha: np.ndarray
    K_inv: np.ndarray
    length_mm: np.ndarray
    amplitude_mm: float
    measured: bool

    @classmethod
    def unmeasured(cls, config: EstimatorConfig | None = None) -> "GridPrint":
        """No print measured: zero displacement, the printer's prior per axis."""
        s = (config or DEFAULT).uncertainty.unmeasured_print_mm / np.sqrt(2.0)
        return cls(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 0)), np.full(2, np.inf),
                   float(s), False)

    @classmethod
    def from_markers(cls, centres_mm, displacement_mm, std_mm,
                     config: EstimatorConfig | None = None) -> "GridPrint":
        """The process through markers at ``centres_mm`` (n, 2) displaced by
        ``displacement_mm`` (n, 2) (printed - declared, in the gauge) with per-axis
        ``std_mm`` (n,)."""
        config = config or DEFAULT
        p = np.asarray(centres_mm, float).reshape(-1, 2)
        y = np.asarray(displacement_mm, float).reshape(-1, 2)
        noise = np.maximum(np.asarray(std_mm, float).ravel(), 1e-4) ** 2
        if len(p) < 3:
            return cls.unmeasured(config)
        s0 = config.uncertainty.unmeasured_print_mm / np.sqrt(2.0)
        dp = p[:, None] - p[None]
        best = None
        g = config.grid
        ells = np.geomspace(g.print_length_min_mm, g.print_length_max_mm, 5)
        lengths = [np.array([a, b]) for a in ells for b in ells]
        for ell in lengths:   # along x and y apart: a feed wave is the same across the page
            D2 = np.sum((dp / ell) ** 2, axis=2)
            for k in np.geomspace(0.5, max(g.print_amplitude_max, 0.5), 7):
                amp = k * s0
                Kx = amp**2 * np.exp(-D2 / 2) + np.diag(noise)
                try:
                    L = np.linalg.cholesky(Kx)
                except np.linalg.LinAlgError:
                    continue
                a = np.linalg.solve(L, y)                       # both axes share the kernel
                ll = -0.5 * float(np.sum(a * a)) - 2.0 * float(np.sum(np.log(np.diag(L))))
                if best is None or ll > best[0]:
                    best = (ll, ell, amp, Kx)
        if best is None:
            return cls.unmeasured(config)
        _, ell, amp, Kx = best
        K_inv = np.linalg.inv(Kx)
        return cls(p, K_inv @ y, K_inv, ell, float(amp), True)

    @classmethod
    def from_as_printed(cls, ap, config: EstimatorConfig | None = None) -> "GridPrint":
        """From a layout as printed (:class:`vision_cal.measure.asprinted.AsPrinted`): each
        marker with all four corners released, its mean corner deviation and the RMS of its
        corners' per-axis std (not divided by four: the corners share the poses' and the
        lens's errors)."""
        rel = np.asarray(ap.released, bool).all(axis=1)
        if not rel.any():
            return cls.unmeasured(config)
        dec = np.asarray(ap.declared_mm, float)[rel]
        dev = np.asarray(ap.deviation_mm, float)[rel]
        sd = np.asarray(ap.std_mm, float)[rel]
        return cls.from_markers(dec.mean(axis=1), dev.mean(axis=1),
                                np.sqrt(np.mean(sd**2, axis=(1, 2))), config)

    def at(self, xy_mm) -> tuple[np.ndarray, np.ndarray]:
        """(D (N, 2), cov (N, 2, 2)): the displacement at sheet points ``xy_mm`` (N, 2)."""
        q = np.asarray(xy_mm, float).reshape(-1, 2)
        var = np.full(len(q), self.amplitude_mm**2)
        D = np.zeros((len(q), 2))
        if len(self.xy_mm):
            ks = self.amplitude_mm**2 * np.exp(
                -np.sum(((q[:, None] - self.xy_mm[None]) / self.length_mm) ** 2, axis=2) / 2)
            D = ks @ self.alpha
            var = np.maximum(var - np.einsum("ij,jk,ik->i", ks, self.K_inv, ks), 0.0)
        return D, var[:, None, None] * np.eye(2)


def against_grid(xy_mm, cov_noise_mm2, offset, gprint: GridPrint):
    """A dot measured against the printed lines around it: (xy (2,), cov (2, 2), the lines'
    offset beyond the print (2,), its cov (2, 2)). ``xy_mm``: the dot through the marker
    mapping, ``cov_noise_mm2`` its own noise; ``offset``: the lines' offset there
    (:class:`vision_cal.measure.grid.GridOffset`: the mapping's error, a raised paper's
    parallax and the printer's displacement); ``gprint``: the printer's displacement, taken
    off, its covariance added to the dot's and to the offset's."""
    D, Dc = gprint.at(xy_mm)
    off = np.asarray(offset.d_mm, float) - D[0]
    oc = np.asarray(offset.cov_mm2, float) + Dc[0]
    return np.asarray(xy_mm, float) - off, np.asarray(cov_noise_mm2, float) + oc, off, oc
