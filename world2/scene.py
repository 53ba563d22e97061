"""What lies on the table: the paper (printed off its layout, toner grown, not flat), the
pen's ink, the table around it. ``Scene.reflectance`` answers for sample points."""

from __future__ import annotations

import cv2
import numpy as np

from .sheet import Layout, MarkerTextures, PaperShape, PrintField

PAPER = np.array([0.90, 0.89, 0.85], np.float32)      # RGB reflectance
TONER = np.array([0.045, 0.045, 0.05], np.float32)
FINE = np.array([0.70, 0.80, 0.90], np.float32)       # graph-paper blue, 1 mm lines
BOLD = np.array([0.50, 0.66, 0.84], np.float32)       # 10 mm lines
INK = np.array([0.16, 0.16, 0.30], np.float32)       # transmittance of the pen's ink
TABLE = np.array([0.33, 0.27, 0.21], np.float32)


def _overlap(lo, hi, a, b):
    return np.clip(np.minimum(hi, b) - np.maximum(lo, a), 0, None)


class Scene:
    def __init__(self, layout: Layout, field: PrintField | None, shape: PaperShape | None,
                 toner_mm: float, marks_xy: np.ndarray, mark_d_mm: np.ndarray,
                 mark_ellipse: np.ndarray, texture_px_per_mm: float = 50.0):
        self.L = layout
        self.toner = toner_mm
        self.tex = MarkerTextures(layout, toner_mm, texture_px_per_mm)
        self._pref: dict[int, dict] = {}
        if field is not None:
            dx, dy, (self.fx0, self.fy0, self.fstep) = field.raster(layout)
            self.fdx, self.fdy = dx, dy
        else:
            self.fdx = None
        self.shape = shape
        self.marks = np.asarray(marks_xy, float).reshape(-1, 2)
        self.mark_r = np.asarray(mark_d_mm, float) / 2
        self.mark_e = np.asarray(mark_ellipse, float).reshape(-1, 2)   # axis ratio, angle rad
        self.visible = np.ones(len(self.marks), bool)

    # -- geometry -----------------------------------------------------------------------
    def height(self, x, y):
        if self.shape is None:
            return np.zeros_like(x)
        (bx, by), (w, h) = self.L.bottom_left_mm, self.L.size_mm
        on = (x >= bx) & (x <= bx + w) & (y >= by) & (y <= by + h)
        return np.where(on, self.shape(x, y), 0.0)

    def intersect(self, eye, d):
        z = np.zeros(d.shape[:-1])
        for _ in range(2):
            s = (z - eye[2]) / d[..., 2]
            x, y = eye[0] + s * d[..., 0], eye[1] + s * d[..., 1]
            z = self.height(x, y)
        return x, y

    def _field(self, x, y):
        mx = ((x - self.fx0) / self.fstep).astype(np.float32)
        my = ((y - self.fy0) / self.fstep).astype(np.float32)
        dx = cv2.remap(self.fdx, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        dy = cv2.remap(self.fdy, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return dx, dy

    def layout_point(self, x, y):
        """Where on the layout the print at paper point (x, y) came from: q + d(q) = p."""
        if self.fdx is None:
            return x, y
        qx, qy = x, y
        for _ in range(3):
            dx, dy = self._field(qx, qy)
            qx, qy = x - dx, y - dy
        return qx, qy

    # -- print --------------------------------------------------------------------------
    def _grid(self, qx, qy, fp):
        """Coverage (fine, bold) of the ruled lines, box-filtered over the footprint."""
        L = self.L
        x0, y0, x1, y1 = L.grid_extent_mm
        inside = (qx >= x0) & (qx <= x1) & (qy >= y0) & (qy <= y1)
        fine, bold = [], []
        for a, lo, hi, origin in ((qx, x0, x1, L.grid_origin_mm[0]), (qy, y0, y1, L.grid_origin_mm[1])):
            k = np.round((a - origin) / L.grid_pitch_mm)
            c = origin + k * L.grid_pitch_mm
            is_bold = (np.abs(k) % L.grid_bold_every) == 0
            w = np.where(is_bold, L.bold_width_mm, L.fine_width_mm) + 2 * self.toner
            f = _overlap(a - fp / 2, a + fp / 2, c - w / 2, c + w / 2) / fp
            f = np.where((c >= lo - 1e-9) & (c <= hi + 1e-9) & inside, f, 0.0)
            fine.append(np.where(is_bold, 0.0, f))
            bold.append(np.where(is_bold, f, 0.0))
        union = lambda a, b: 1 - (1 - a) * (1 - b)      # noqa: E731
        return union(*fine), union(*bold)

    def _markers(self, qx, qy, fp):
        k = max(1, int(round(fp * self.tex.s))) | 1
        if k not in self._pref:
            self._pref[k] = self.tex.prefiltered(fp)
        tex = self._pref[k]
        white = np.full(qx.shape, 255.0, np.float32)
        xmin, xmax, ymin, ymax = qx.min(), qx.max(), qy.min(), qy.max()
        for mid, t in tex.items():
            left, top, kpx = self.tex.box[mid]
            right, bottom = left + t.shape[1] / kpx, top - t.shape[0] / kpx
            if right < xmin or left > xmax or top < ymin or bottom > ymax:
                continue
            mu = ((qx - left) * kpx - 0.5).astype(np.float32)
            mv = ((top - qy) * kpx - 0.5).astype(np.float32)
            s = cv2.remap(t, mu, mv, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                          borderValue=255)
            np.minimum(white, s.astype(np.float32), out=white)
        return 1 - white / 255.0

    # -- ink ----------------------------------------------------------------------------
    def _ink(self, x, y, fp):
        cov = np.zeros(x.shape, np.float32)
        lo_x, hi_x, lo_y, hi_y = x.min(), x.max(), y.min(), y.max()
        for i in np.flatnonzero(self.visible):
            (mx, my), r = self.marks[i], self.mark_r[i]
            if mx + r < lo_x or mx - r > hi_x or my + r < lo_y or my - r > hi_y:
                continue
            near = (np.abs(x - mx) < r + fp) & (np.abs(y - my) < r + fp)
            if not near.any():
                continue
            ratio, ang = self.mark_e[i]
            dx, dy = x[near] - mx, y[near] - my
            a = np.cos(ang) * dx + np.sin(ang) * dy
            b = (-np.sin(ang) * dx + np.cos(ang) * dy) / ratio
            d = np.hypot(a, b)
            c = np.clip((r - d) / fp + 0.5, 0, 1)
            cov[near] = np.maximum(cov[near], c)
        return cov

    def reflectance(self, x, y, fp):
        """RGB reflectance (H, W, 3) float32 at paper points (H, W)."""
        (bx, by), (w, h) = self.L.bottom_left_mm, self.L.size_mm
        on = (x >= bx) & (x <= bx + w) & (y >= by) & (y <= by + h)
        qx, qy = self.layout_point(x, y)
        fine, bold = (c.astype(np.float32)[..., None] for c in self._grid(qx, qy, fp))
        black = self._markers(qx, qy, fp).astype(np.float32)[..., None]
        refl = PAPER * (1 - fine * (1 - FINE)) * (1 - bold * (1 - BOLD))
        refl = refl * (1 - black) + TONER * black
        ink = self._ink(x, y, fp)[..., None] * 0.92
        refl = refl * (1 - ink * (1 - INK))
        refl[~on] = TABLE
        return refl.astype(np.float32)
