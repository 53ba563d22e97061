"""The sheet as a raster at a chosen dpi (exact area coverage, no rasteriser library).

Pixel convention (the same as the renderer's textures, ``vision_cal.world.sheet``): row 0
at the top (y = y_max); pixel (row i, col j) covers the square of side 1/px_per_mm whose
centre is ``x = x_min + (j + 0.5) / ppm``, ``y = y_max - (i + 0.5) / ppm``, with
``ppm = dpi / 25.4``. Rectangles and marker modules are painted with their exact pixel
coverage (separable 1-D overlaps; a marker's modules as one union, so no seams), polygons
with 8 x 8 supersampling, text with Pillow's scalable font (text is not geometry).
"""

from __future__ import annotations

from io import BytesIO

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from vision_cal.errors import VisionCalError
from vision_cal.sheet.layout import MarkerCells, Poly, Rect, SheetLayout, Text

MAX_PIXELS = 400e6


def _overlap(lo_px: np.ndarray, a, b) -> np.ndarray:
    """Fraction of unit pixel intervals [lo, lo+1) covered by intervals [a, b)."""
    return np.clip(np.minimum(lo_px + 1.0, b) - np.maximum(lo_px, a), 0.0, 1.0)


class Canvas:
    def __init__(self, layout: SheetLayout, ppm: float):
        self.ppm = float(ppm)
        self.x0, self.y0, self.x1, self.y1 = layout.extent_mm
        W, H = layout.size_mm
        self.W, self.H = int(round(W * ppm)), int(round(H * ppm))
        if self.W * self.H > MAX_PIXELS:
            raise VisionCalError(f"a {self.W} x {self.H} px raster is too large; choose a "
                                 "lower dpi", field="--png-dpi")
        if self.W < 1 or self.H < 1:
            raise VisionCalError("the raster would be empty; choose a higher dpi",
                                 field="--png-dpi")
        self.img = np.full((self.H, self.W, 3), 255, np.uint8)

    def draw(self, p) -> None:
        """Draw one layout primitive (the one dispatch: the sheet's PNG and the print model
        of :mod:`vision_cal.measure.printed` both draw through it)."""
        if isinstance(p, Rect):
            self.rect(p)
        elif isinstance(p, MarkerCells):
            self.marker(p)
        elif isinstance(p, Poly):
            self.poly(p)
        elif isinstance(p, Text):
            self.text(p)
        else:  # pragma: no cover
            raise TypeError(f"no raster writer for {type(p).__name__}")

    def u(self, x):
        return (np.asarray(x, float) - self.x0) * self.ppm

    def v(self, y):
        return (self.y1 - np.asarray(y, float)) * self.ppm

    def _axes(self, xs_mm, ys_mm):
        """Pixel box and coverage of cells between consecutive xs (cols) and ys (rows)."""
        u = self.u(xs_mm)
        v = self.v(np.asarray(ys_mm, float)[::-1])
        c0, c1 = max(int(np.floor(u[0])), 0), min(int(np.ceil(u[-1])), self.W)
        r0, r1 = max(int(np.floor(v[0])), 0), min(int(np.ceil(v[-1])), self.H)
        if c1 <= c0 or r1 <= r0:
            return None
        cx = _overlap(np.arange(c0, c1, dtype=float)[:, None], u[None, :-1], u[None, 1:])
        cy = _overlap(np.arange(r0, r1, dtype=float)[:, None], v[None, :-1], v[None, 1:])
        return slice(r0, r1), slice(c0, c1), cy, cx

    def blend(self, rs, cs, cov, rgb):
        patch = self.img[rs, cs].astype(np.float32)
        cov = cov.astype(np.float32)[..., None]
        patch += (np.asarray(rgb, np.float32) - patch) * cov
        self.img[rs, cs] = np.clip(np.rint(patch), 0, 255).astype(np.uint8)

    def rect(self, p: Rect):
        a = self._axes([p.x0, p.x1], [p.y0, p.y1])
        if a is not None:
            rs, cs, cy, cx = a
            self.blend(rs, cs, cy[:, :1] * cx[:, 0][None, :], p.rgb)

    def marker(self, p: MarkerCells):
        n = p.bits.shape[0]
        edges = np.arange(n + 1) * p.module_mm
        a = self._axes(p.x0 + edges, p.y0 + edges)
        if a is not None:
            rs, cs, cy, cx = a
            self.blend(rs, cs, cy @ p.bits.astype(float) @ cx.T, (0, 0, 0))

    def poly(self, p: Poly, ss: int = 8):
        # OpenCV takes 0.2 s to import: loaded here, when used
        import cv2

        pts = np.column_stack([self.u([q[0] for q in p.points]), self.v([q[1] for q in p.points])])
        c0, r0 = np.maximum(np.floor(pts.min(axis=0)).astype(int), 0)
        c1 = min(int(np.ceil(pts[:, 0].max())), self.W)
        r1 = min(int(np.ceil(pts[:, 1].max())), self.H)
        if c1 <= c0 or r1 <= r0:
            return
        m = np.zeros(((r1 - r0) * ss, (c1 - c0) * ss), np.uint8)
        q = np.round(((pts - [c0, r0]) * ss - 0.5) * 16).astype(np.int32)
        cv2.fillPoly(m, [q], 1, cv2.LINE_8, 4)
        cov = m.reshape(r1 - r0, ss, c1 - c0, ss).mean(axis=(1, 3))
        self.blend(slice(r0, r1), slice(c0, c1), cov, p.rgb)

    def text(self, p: Text):
        px = p.size_mm * self.ppm
        if px < 5:
            return  # unreadable at this dpi anyway
        font = ImageFont.load_default(size=px)
        anchor = {"start": "ls", "middle": "ms", "end": "rs"}[p.anchor]
        l, t, r, b = font.getbbox(p.text, anchor=anchor)
        im = Image.new("L", (int(np.ceil(r - l)) + 2, int(np.ceil(b - t)) + 2), 0)
        ImageDraw.Draw(im).text((1 - l, 1 - t), p.text, fill=255, font=font, anchor=anchor)
        ax, ay = 1 - l, 1 - t                       # the anchor in the small image
        if p.angle_deg:
            w = im.size[0]
            im = im.rotate(90, expand=True)
            ax, ay = ay, w - ax
        a = np.asarray(im, np.float32) / 255.0
        c0 = int(round(float(self.u(p.x)) - ax))
        r0 = int(round(float(self.v(p.y)) - ay))
        h, w = a.shape
        rr0, cc0 = max(r0, 0), max(c0, 0)
        rr1, cc1 = min(r0 + h, self.H), min(c0 + w, self.W)
        if rr1 <= rr0 or cc1 <= cc0:
            return
        self.blend(slice(rr0, rr1), slice(cc0, cc1),
                   a[rr0 - r0:rr1 - r0, cc0 - c0:cc1 - c0], p.rgb)


def rasterise(layout: SheetLayout, dpi: float) -> np.ndarray:
    """(H, W, 3) uint8 RGB of the sheet at ``dpi`` (see the module docstring)."""
    if not (np.isfinite(dpi) and dpi > 0):
        raise VisionCalError(f"expected a positive dpi, got {dpi!r}", field="--png-dpi")
    cv = Canvas(layout, dpi / 25.4)
    for p in layout.primitives:
        cv.draw(p)
    return cv.img


def png_bytes(layout: SheetLayout, dpi: float) -> bytes:
    img = Image.fromarray(rasterise(layout, dpi), "RGB")
    buf = BytesIO()
    img.save(buf, format="PNG", dpi=(dpi, dpi))
    return buf.getvalue()
