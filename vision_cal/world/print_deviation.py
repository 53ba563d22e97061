"""A sheet printed off its layout: the printer's displacement of the ink (the world's only).

A printer does not put the ink where the layout says. Two things are modelled:

- **a smooth displacement field in the paper's plane**: the printed content whose layout
  position is p lands on the paper at ``p + d(p)``, with

      d_x = a1 sin(2 pi y / lam1 + ph1)                      (a wave along the paper feed, y)
          + s v                                               (skew: the feed not square)
      d_y = a2 sin(2 pi y / lam2 + ph2) + b (u^2 - 1/3)       (feed speed wobble, a bow)

  (u, v) in [-1, 1] across the paper; amplitudes, wavelengths (120..300 mm) and phases are
  drawn from the scene seed. The best-fitting similarity of the displaced marker corners
  to their layout positions is then removed (no overall shift, turn or scale: the
  markers define the sheet frame on average, and the bars and ``sheet_affine`` cover the
  paper's overall scale), and the field is scaled to ``rms_mm`` over the paper.
- **toner growth**: the markers' black squares grow ``toner_mm`` on every side (the
  detected corners of a marker move outward by ``toner_mm`` in x and in y).

A printed marker's sides are then not straight: the feed wave curves them (by about
``a1 (2 pi / lam1)^2 h^2 / 2`` over a side of half-length ``h``; 0.02 mm for a 30 mm marker
and a 150 mm wave). Its corner *points* (``printed_corners``, truth.json ``print.markers``)
are where the ink's corners are; a detector that fits straight lines to the sides and
intersects them reads ``straight_side_corners`` instead (truth.json
``print.markers_straight_sides``), off the points by ``-0.4 h^2`` times the field's
curvature along the side: across the sheet that follows the wave and, over a few marker
rows, looks like a shear (seed 2871 of renders/printed_off_six.yaml: -1.4e-4 x y, 0.026 mm
at the outer rows).

The pen's ink is not displaced: it lands where the robot puts it, in the paper's own
millimetres. This is the world's own implementation; the estimator never imports it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: evaluation grid step over the paper for the field's RMS and maximum (mm)
_GRID_STEP_MM = 5.0
#: the part of each printed side a straight-line fit reads (fractions of the side) and the
#: number of points taken there (``PrintField.straight_side_corners``)
STRAIGHT_SIDE_SPAN = (0.12, 0.88)
_STRAIGHT_SIDE_POINTS = 16


@dataclass(frozen=True)
class PrintScene:
    """Scene ``sheet.print``: ``deviation_rms_mm`` the field's RMS over the paper (0: none),
    ``toner_mm`` the growth of the markers' black squares per side."""

    deviation_rms_mm: float = 0.0
    toner_mm: float = 0.0

    @property
    def is_exact(self) -> bool:
        return self.deviation_rms_mm <= 0 and self.toner_mm <= 0

    def field(self, extent_mm, marker_corners_mm, seed: int) -> "PrintField":
        """The field for a paper ``extent_mm`` whose markers' layout corners are
        ``marker_corners_mm`` (M, 4, 2), drawn from ``seed``."""
        rng = np.random.default_rng([int(seed), 2801])
        x0, y0, x1, y1 = (float(v) for v in extent_mm)
        raw = {"a1": rng.uniform(0.5, 1.0) * rng.choice([-1, 1]),
               "lam1": rng.uniform(120.0, 300.0), "ph1": rng.uniform(0, 2 * np.pi),
               "a2": rng.uniform(0.3, 0.8) * rng.choice([-1, 1]),
               "lam2": rng.uniform(120.0, 300.0), "ph2": rng.uniform(0, 2 * np.pi),
               "b": rng.uniform(0.5, 1.0) * rng.choice([-1, 1]),
               "s": rng.uniform(0.2, 0.5) * rng.choice([-1, 1])}
        f = PrintField((x0, y0, x1, y1), raw, np.zeros(4), 1.0, float(self.toner_mm))
        if self.deviation_rms_mm <= 0:
            return PrintField((x0, y0, x1, y1), raw, np.zeros(4), 0.0, float(self.toner_mm))
        c = np.asarray(marker_corners_mm, float).reshape(-1, 2)
        sim = _similarity_fit(c, f.raw(c))
        f = PrintField((x0, y0, x1, y1), raw, sim, 1.0, float(self.toner_mm))
        rms = float(np.sqrt(np.mean(np.sum(f.displacement(f.paper_grid()) ** 2, axis=1))))
        return PrintField((x0, y0, x1, y1), raw, sim, self.deviation_rms_mm / max(rms, 1e-12),
                          float(self.toner_mm))

    def to_json(self) -> dict:
        return {"deviation_rms_mm": self.deviation_rms_mm, "toner_mm": self.toner_mm}


def _similarity_fit(p: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(tx, ty, a, b): the displacement ``d`` (N, 2) at ``p`` best fitted by the small
    similarity d = t + [[a, -b], [b, a]] p (least squares)."""
    n = len(p)
    A = np.zeros((2 * n, 4))
    A[0::2, 0] = 1.0
    A[1::2, 1] = 1.0
    A[0::2, 2], A[0::2, 3] = p[:, 0], -p[:, 1]
    A[1::2, 2], A[1::2, 3] = p[:, 1], p[:, 0]
    sol, *_ = np.linalg.lstsq(A, d.reshape(-1), rcond=None)
    return sol


@dataclass(frozen=True)
class PrintField:
    """The printer's displacement: layout point p is printed at ``p + displacement(p)``."""

    extent_mm: tuple[float, float, float, float]
    params: dict
    similarity: np.ndarray     # (tx, ty, a, b) removed from the raw field
    scale: float               # the raw field's factor (0: no displacement)
    toner_mm: float = 0.0

    @property
    def moves(self) -> bool:
        return self.scale > 0

    def _uv(self, x, y):
        x0, y0, x1, y1 = self.extent_mm
        return (2 * (x - x0) / (x1 - x0) - 1, 2 * (y - y0) / (y1 - y0) - 1)

    def raw(self, p) -> np.ndarray:
        p = np.asarray(p, float).reshape(-1, 2)
        dx, dy = self._raw_xy(p[:, 0], p[:, 1])
        return np.column_stack([dx, dy])

    def _raw_xy(self, x, y):
        k = self.params
        u, v = self._uv(x, y)
        dx = k["a1"] * np.sin(2 * np.pi * y / k["lam1"] + k["ph1"]) + k["s"] * v
        dy = k["a2"] * np.sin(2 * np.pi * y / k["lam2"] + k["ph2"]) + k["b"] * (u * u - 1 / 3)
        return dx + 0 * x, dy + 0 * y

    def displacement_xy(self, x, y):
        """(dx, dy) at broadcastable arrays x, y (mm)."""
        if not self.moves:
            return np.zeros(np.broadcast(x, y).shape), np.zeros(np.broadcast(x, y).shape)
        dx, dy = self._raw_xy(x, y)
        tx, ty, a, b = self.similarity
        return (self.scale * (dx - (tx + a * x - b * y)),
                self.scale * (dy - (ty + b * x + a * y)))

    def displacement(self, p) -> np.ndarray:
        p = np.asarray(p, float).reshape(-1, 2)
        dx, dy = self.displacement_xy(p[:, 0], p[:, 1])
        return np.column_stack([dx, dy])

    def printed_at(self, p) -> np.ndarray:
        """Where layout points ``p`` (N, 2) are on the paper."""
        p = np.asarray(p, float).reshape(-1, 2)
        return p + self.displacement(p)

    def layout_at(self, x, y):
        """The layout point printed at paper point (x, y) (broadcast arrays; the inverse of
        :meth:`printed_at`, by fixed-point iteration: the field is smooth and small)."""
        px, py = np.asarray(x, float), np.asarray(y, float)
        lx, ly = px, py
        for _ in range(3):
            dx, dy = self.displacement_xy(lx, ly)
            lx, ly = px - dx, py - dy
        return lx, ly

    def paper_grid(self) -> np.ndarray:
        x0, y0, x1, y1 = self.extent_mm
        xs = np.arange(x0, x1 + 1e-9, _GRID_STEP_MM)
        ys = np.arange(y0, y1 + 1e-9, _GRID_STEP_MM)
        X, Y = np.meshgrid(xs, ys)
        return np.column_stack([X.ravel(), Y.ravel()])

    def printed_corners(self, marker_corners_mm) -> np.ndarray:
        """The markers' corners (M, 4, 2) as printed: grown by the toner (outward from the
        marker's centre, ``toner_mm`` in x and y), then displaced."""
        c = np.asarray(marker_corners_mm, float).reshape(-1, 4, 2)
        centre = c.mean(axis=1, keepdims=True)
        grown = c + self.toner_mm * np.sign(c - centre)
        return self.printed_at(grown.reshape(-1, 2)).reshape(c.shape)

    def straight_side_corners(self, marker_corners_mm) -> np.ndarray:
        """The markers' corners (M, 4, 2) as straight sides meet: each printed side (the
        grown layout side, displaced) sampled over ``STRAIGHT_SIDE_SPAN``, a straight line
        fitted through it (total least squares), corner k where side k-1 meets side k
        (side k runs from corner k to k+1). Equal to :meth:`printed_corners` where the field
        is affine over the marker."""
        c = np.asarray(marker_corners_mm, float).reshape(-1, 4, 2)
        centre = c.mean(axis=1, keepdims=True)
        grown = c + self.toner_mm * np.sign(c - centre)
        t = np.linspace(*STRAIGHT_SIDE_SPAN, _STRAIGHT_SIDE_POINTS)
        a, b = grown, np.roll(grown, -1, axis=1)
        pts = a[:, :, None, :] + t[None, None, :, None] * (b - a)[:, :, None, :]
        pts = self.printed_at(pts.reshape(-1, 2)).reshape(pts.shape)      # (M, 4, n, 2)
        mid = pts.mean(axis=2)
        d = pts - mid[:, :, None, :]
        _, vec = np.linalg.eigh(np.einsum("mkni,mknj->mkij", d, d))
        dirn = vec[..., :, 1]                                              # (M, 4, 2)
        p1, d1 = np.roll(mid, 1, axis=1), np.roll(dirn, 1, axis=1)         # side k - 1
        A = np.stack([d1, -dirn], axis=-1)                                 # (M, 4, 2, 2)
        s = np.linalg.solve(A, (mid - p1)[..., None])[..., 0, 0]
        return p1 + s[..., None] * d1

    def to_json(self, marker_ids, marker_corners_mm) -> dict:
        """truth.json ``print``: the field's parameters, its RMS and maximum over the paper
        and at the marker corners, every marker's corners as printed (the points) and as
        its straight-fitted sides meet (``markers_straight_sides``), and the RMS of their
        difference (``straight_side_rms_mm``)."""
        g = self.displacement(self.paper_grid())
        c = np.asarray(marker_corners_mm, float).reshape(-1, 4, 2)
        dc = self.displacement(c.reshape(-1, 2))
        pc, sc = self.printed_corners(c), self.straight_side_corners(c)
        n = np.linalg.norm
        return {"params": {k: float(v) for k, v in self.params.items()},
                "removed_similarity": [float(v) for v in self.similarity],
                "scale": float(self.scale), "toner_mm": self.toner_mm,
                "rms_mm": float(np.sqrt(np.mean(np.sum(g**2, axis=1)))),
                "max_mm": float(n(g, axis=1).max()),
                "corner_rms_mm": float(np.sqrt(np.mean(np.sum(dc**2, axis=1)))),
                "corner_max_mm": float(n(dc, axis=1).max()),
                "markers": {str(int(i)): v.tolist() for i, v in zip(marker_ids, pc)},
                "markers_straight_sides": {str(int(i)): v.tolist() for i, v in
                                           zip(marker_ids, sc)},
                "straight_side_rms_mm": float(np.sqrt(np.mean(np.sum((sc - pc)**2,
                                                                     axis=2))))}
