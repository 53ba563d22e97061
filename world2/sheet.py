"""The paper: its layout (markers and ruled grid), the printer's errors, its shape.

Everything here is in sheet millimetres (x right, y up, the layout's frame). Three things
differ between what the layout says and what lies on the table:

- ``PrintField``: the printed content (markers and grid) lands displaced by a smooth field
  (drum speed, feed skew, a bowed page). Built from smoothed noise on a coarse lattice,
  interpolated by a cubic spline; its translation, turn and scale over the markers' corners
  are taken out (the sheet frame is, by the contract, the one the markers define), then it
  is scaled to the asked RMS over the paper.
- toner growth: every black edge moves outward by ``toner_mm`` (markers and lines).
- ``PaperShape``: the paper is not flat; a gentle bow and one curled corner, its height
  above the table in mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.interpolate import RectBivariateSpline
from scipy.ndimage import gaussian_filter


@dataclass(frozen=True)
class Layout:
    """The declared sheet (what session.json's ``sheet`` block says)."""

    dictionary: str
    markers: dict[int, np.ndarray]        # id -> (4, 2) corners TL, TR, BR, BL (y up)
    size_mm: tuple[float, float]
    bottom_left_mm: tuple[float, float]
    grid_pitch_mm: float
    grid_bold_every: int
    grid_origin_mm: tuple[float, float]
    grid_extent_mm: tuple[float, float, float, float]   # x0, y0, x1, y1
    fine_width_mm: float = 0.1
    bold_width_mm: float = 0.25

    def sheet_block(self) -> dict:
        return {
            "aruco_dictionary": self.dictionary,
            "markers": [{"id": int(i), "corners_mm": np.round(c, 4).tolist()}
                        for i, c in sorted(self.markers.items())],
            "size_mm": list(self.size_mm),
            "bottom_left_mm": list(self.bottom_left_mm),
            "grid": {"pitch_mm": self.grid_pitch_mm, "bold_every": self.grid_bold_every,
                     "origin_mm": list(self.grid_origin_mm)},
        }

    def marker_corners(self) -> np.ndarray:
        """All markers' corners (4M, 2)."""
        return np.concatenate([self.markers[i] for i in sorted(self.markers)])


def a2_layout(dictionary: str = "DICT_6X6_250", marker_mm: float = 24.0) -> Layout:
    """World2's own sheet: A2 landscape, a ring of 16 markers, a 1 mm grid inside."""
    w, h = 594.0, 420.0
    x0, y0 = -w / 2, -h / 2
    margin = 12.0
    xs = np.linspace(x0 + margin, x0 + w - margin - marker_mm, 6)
    ys = np.linspace(y0 + margin, y0 + h - margin - marker_mm, 4)
    places = [(x, ys[0]) for x in xs] + [(x, ys[-1]) for x in xs]
    places += [(xs[0], y) for y in ys[1:-1]] + [(xs[-1], y) for y in ys[1:-1]]
    markers = {}
    for k, (mx, my) in enumerate(places):
        s = marker_mm
        markers[10 + 3 * k] = np.array([[mx, my + s], [mx + s, my + s], [mx + s, my], [mx, my]])
    inner = margin + marker_mm + 8.0
    extent = (x0 + inner, y0 + inner, x0 + w - inner, y0 + h - inner)
    return Layout(dictionary, markers, (w, h), (x0, y0), 1.0, 10, (0.0, 0.0), extent)


def layout_from_sheet(block: dict) -> Layout:
    """A Layout from a contract ``sheet`` block (e.g. ``vision-cal sheet``'s sheet.json)."""
    markers = {int(m["id"]): np.asarray(m["corners_mm"], float) for m in block["markers"]}
    allc = np.concatenate(list(markers.values()))
    size = tuple(block.get("size_mm", np.ptp(allc, axis=0) + 40.0))
    bl = tuple(block.get("bottom_left_mm", allc.min(axis=0) - 20.0))
    g = block.get("grid") or {}
    ext = g.get("extent_mm") or [bl[0] + 40, bl[1] + 40, bl[0] + size[0] - 40, bl[1] + size[1] - 40]
    return Layout(block["aruco_dictionary"], markers, size, bl, g.get("pitch_mm", 1.0),
                  g.get("bold_every", 10), tuple(g.get("origin_mm", (0.0, 0.0))), tuple(ext),
                  g.get("fine_width_mm", 0.1), g.get("bold_width_mm", 0.25))


class PrintField:
    """Smooth in-plane displacement of the print (mm), zero similarity over the markers."""

    def __init__(self, layout: Layout, rms_mm: float, rng: np.random.Generator,
                 lattice: tuple[int, int] = (9, 7), smooth: float = 1.2):
        (bx, by), (w, h) = layout.bottom_left_mm, layout.size_mm
        self.gx = np.linspace(bx, bx + w, lattice[0])
        self.gy = np.linspace(by, by + h, lattice[1])
        raw = [gaussian_filter(rng.standard_normal(lattice[::-1]), smooth, mode="nearest")
               for _ in range(2)]
        self._splines = [RectBivariateSpline(self.gy, self.gx, r, kx=3, ky=3) for r in raw]
        self._sim = np.zeros(4)
        self._scale = 1.0
        corners = layout.marker_corners()
        self._sim = self._similarity(corners)
        px, py = np.meshgrid(np.linspace(bx, bx + w, 120), np.linspace(by, by + h, 90))
        d = self(np.column_stack([px.ravel(), py.ravel()]))
        self._scale = rms_mm / max(np.sqrt(np.mean(np.sum(d**2, axis=1))), 1e-12)

    def _raw(self, xy: np.ndarray) -> np.ndarray:
        return np.column_stack([s.ev(xy[:, 1], xy[:, 0]) for s in self._splines])

    def _similarity(self, xy: np.ndarray) -> np.ndarray:
        """Least-squares [tx, ty, a, b] of the field at xy as t + [[a, -b], [b, a]] xy."""
        c = xy - xy.mean(axis=0)
        d = self._raw(xy)
        n = len(xy)
        A = np.zeros((2 * n, 4))
        A[0::2, 0] = 1
        A[1::2, 1] = 1
        A[0::2, 2], A[0::2, 3] = c[:, 0], -c[:, 1]
        A[1::2, 2], A[1::2, 3] = c[:, 1], c[:, 0]
        p = np.linalg.lstsq(A, d.ravel(), rcond=None)[0]
        self._centre = xy.mean(axis=0)
        return p

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        """Displacement (N, 2) mm of the print at layout points xy (N, 2)."""
        xy = np.atleast_2d(xy)
        d = self._raw(xy)
        if np.any(self._sim):
            tx, ty, a, b = self._sim
            c = xy - self._centre
            d = d - np.column_stack([tx + a * c[:, 0] - b * c[:, 1], ty + b * c[:, 0] + a * c[:, 1]])
        return d * self._scale

    def raster(self, layout: Layout, step_mm: float = 1.0):
        """The field on a regular grid: (dx, dy) float32 images and their origin, for remap."""
        (bx, by), (w, h) = layout.bottom_left_mm, layout.size_mm
        xs = np.arange(bx - 5, bx + w + 5 + step_mm, step_mm)
        ys = np.arange(by - 5, by + h + 5 + step_mm, step_mm)
        X, Y = np.meshgrid(xs, ys)
        d = self(np.column_stack([X.ravel(), Y.ravel()]))
        return (d[:, 0].reshape(X.shape).astype(np.float32),
                d[:, 1].reshape(X.shape).astype(np.float32), (xs[0], ys[0], step_mm))


class PaperShape:
    """Height of the paper above the table (mm): a bow along x and one lifted corner."""

    def __init__(self, layout: Layout, peak_mm: float, rng: np.random.Generator):
        (self.bx, self.by), (self.w, self.h) = layout.bottom_left_mm, layout.size_mm
        self.peak = peak_mm
        self.corner = int(rng.integers(4))
        self.bow_share = rng.uniform(0.4, 0.7)

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        u = np.clip((x - self.bx) / self.w, 0, 1)
        v = np.clip((y - self.by) / self.h, 0, 1)
        bow = np.sin(np.pi * u) ** 2
        cu = u if self.corner in (1, 2) else 1 - u
        cv = v if self.corner in (2, 3) else 1 - v
        curl = np.clip(1.0 - np.hypot(1 - cu, 1 - cv) / 0.35, 0, 1) ** 2
        return self.peak * (self.bow_share * bow + (1 - self.bow_share) * curl)


class MarkerTextures:
    """Each marker's printed square at ``px_per_mm`` (uint8, 0 black, 255 paper), toner
    grown; sampled with cv2.remap at layout coordinates."""

    def __init__(self, layout: Layout, toner_mm: float, px_per_mm: float = 50.0,
                 margin_mm: float = 1.0):
        self.s = float(px_per_mm)
        self.margin = margin_mm
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, layout.dictionary))
        nbits = d.markerSize + 2
        self.tex: dict[int, np.ndarray] = {}
        self.box: dict[int, tuple[float, float, float]] = {}   # left, top, px per mm
        for mid, c in layout.markers.items():
            x0, y0 = c[:, 0].min(), c[:, 1].min()
            side = c[:, 0].max() - x0
            px_mod = int(round(side * self.s / nbits))
            img = cv2.aruco.generateImageMarker(d, mid, px_mod * nbits, borderBits=1)
            side_px = px_mod * nbits
            k_px = side_px / side          # this marker's exact px per mm
            m = int(round(margin_mm * k_px))
            r = int(round(toner_mm * k_px))
            canvas = np.full((side_px + 2 * m, side_px + 2 * m), 255, np.uint8)
            canvas[m:m + side_px, m:m + side_px] = img
            if r > 0:   # toner: black grows by r px (white eroded by a disc)
                k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
                canvas = cv2.erode(canvas, k)
            # texture row 0 is the marker's top (largest y); scale to the exact side
            self.tex[mid] = canvas
            self.box[mid] = (x0 - m / k_px, y0 + side + m / k_px, k_px)

    def prefiltered(self, footprint_mm: float) -> dict[int, np.ndarray]:
        """Textures box-filtered over one sample's footprint (anti-aliasing)."""
        k = max(1, int(round(footprint_mm * self.s))) | 1   # odd: an even box moves by half a texel
        return {i: cv2.blur(t, (k, k)) if k > 1 else t for i, t in self.tex.items()}
