"""What is printed under a pen mark: the sheet's own layout, when the sheet says which
generator drew it.

A sheet written by ``vision-cal sheet`` names its generator, version, page and marker
geometry in ``sheet.printed`` (docs/format.md); from these the layout is rebuilt
(:func:`vision_cal.sheet.layout.make_layout`) and accepted only when it reproduces the
declared ``sheet_id`` and every declared marker corner. Then the measurer knows the print
around each mark: :meth:`PrintedReference.predict_patch` renders it (the sheet's own raster
writer, :mod:`vision_cal.sheet.png`) into a photo patch through the sheet mapping, blurred
as the photo is, and :func:`vision_cal.measure.dots.refine_dot` measures the pen's ink
against that instead of the printed ink. :meth:`PrintedReference.content_near` names what
is printed near a point (axes, scale bars, text, numbers, the title), for the reasons of
marks that still cannot be separated and for ``design`` / ``plan``.

A sheet nobody describes (another generator, no ``printed`` block) has no reference; the
dot's local background is then modelled robustly from the photo alone (``refine_dot``).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from functools import lru_cache
from types import SimpleNamespace

import cv2
import numpy as np

from vision_cal.dataset.session import Sheet
from vision_cal.errors import VisionCalError
from vision_cal.sheet.layout import (ANNOT_RGB, GENERATOR, MarkerCells, Poly, Rect, Text,
                                     make_layout, text_width_mm)
from vision_cal.sheet.png import Canvas

#: raster scale of the reference when the sheet does not say the dpi of its own PNG
DEFAULT_PX_PER_MM = 20.0
#: blur of the print in the photo (Gaussian sigma), tried in units of the photo's mm/px
BLUR_CANDIDATES_PX = (0.3, 0.5, 0.7, 0.9, 1.2)


@dataclass(frozen=True)
class PrintedItem:
    """One printed primitive other than the plotting grid: its kind (``axis``, ``arrow``,
    ``scale bar``, ``text``, ``number``, ``title``, ``marker``), a label, its box
    [x0, y0, x1, y1] (sheet mm)."""

    kind: str
    label: str
    box_mm: tuple


@dataclass(frozen=True)
class PrintedReference:
    """The print of a sheet ``layout`` (a :class:`vision_cal.sheet.layout.SheetLayout`),
    rasterised at ``px_per_mm`` when asked."""

    layout: object
    px_per_mm: float
    items: tuple = field(default=())          # PrintedItem, the non-grid content
    _prims: tuple = field(default=(), repr=False)   # (box, primitive) for every primitive

    # ------------------------------------------------------------------ what is printed
    def content_near(self, xy_mm, r_mm: float) -> list[PrintedItem]:
        """The printed items (not the grid) within ``r_mm`` of ``xy_mm`` (their boxes)."""
        x, y = (float(v) for v in np.asarray(xy_mm, float).reshape(2))
        out = []
        for it in self.items:
            x0, y0, x1, y1 = it.box_mm
            dx = max(x0 - x, 0.0, x - x1)
            dy = max(y0 - y, 0.0, y - y1)
            if math.hypot(dx, dy) <= r_mm:
                out.append(it)
        return out

    def ungridded_boxes_mm(self) -> np.ndarray:
        """(K, 4) boxes of everything printed that is not the plotting grid (items, and the
        bare-paper bands and label boxes that interrupt it), for the local grid reference
        to leave out."""
        boxes = [it.box_mm for it in self.items]
        boxes += [b for b, p in self._prims if isinstance(p, Rect) and p.rgb == (255, 255, 255)]
        return np.asarray(boxes, float).reshape(-1, 4)

    # ------------------------------------------------------------------ rendering
    def window(self, box_mm) -> tuple[np.ndarray, float, float]:
        """The print over ``box_mm`` [x0, y0, x1, y1]: (H, W, 3) float32 transmission
        (1 = bare paper) on the full raster's pixel grid, and the sheet (x, y) of its
        top-left pixel corner."""
        lay = self.layout
        ppm = self.px_per_mm
        X0, _, _, Y1 = lay.extent_mm
        x0, y0, x1, y1 = (float(v) for v in box_mm)
        c0 = math.floor((x0 - X0) * ppm)
        c1 = math.ceil((x1 - X0) * ppm)
        r0 = math.floor((Y1 - y1) * ppm)
        r1 = math.ceil((Y1 - y0) * ppm)
        wx0, wy1 = X0 + c0 / ppm, Y1 - r0 / ppm
        ext = (wx0, Y1 - r1 / ppm, X0 + c1 / ppm, wy1)
        cv = Canvas(SimpleNamespace(extent_mm=ext, size_mm=(ext[2] - ext[0], ext[3] - ext[1])),
                     ppm)
        for b, p in self._prims:
            if b[2] < ext[0] or b[0] > ext[2] or b[3] < ext[1] or b[1] > ext[3]:
                continue
            cv.draw(p)
        return cv.img.astype(np.float32) / 255.0, wx0, wy1

    def transmission_at(self, X_mm: np.ndarray, Y_mm: np.ndarray) -> np.ndarray:
        """(3, *X.shape) the sharp print's transmission per channel at sheet points."""
        X_mm = np.asarray(X_mm, float)
        Y_mm = np.asarray(Y_mm, float)
        img, wx0, wy1 = self.window((X_mm.min() - 0.5, Y_mm.min() - 0.5, X_mm.max() + 0.5,
                                     Y_mm.max() + 0.5))
        ppm = self.px_per_mm
        mx = ((X_mm - wx0) * ppm - 0.5).astype(np.float32)
        my = ((wy1 - Y_mm) * ppm - 0.5).astype(np.float32)
        out = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return np.moveaxis(out.reshape(*X_mm.shape, 3), -1, 0)

    def predict_patch(self, mapping, origin_px, shape_hw, centre_mm, half_mm: float,
                      blur_mm: float) -> np.ndarray | None:
        """(3, h, w) the print's transmission per channel at each raw pixel of a photo patch
        (top-left raw pixel ``origin_px``), seen through ``mapping`` with a Gaussian blur of
        ``blur_mm``; None when nothing but bare paper and grid lines is near."""
        c = np.asarray(centre_mm, float).reshape(2)
        pad = 3.0 * blur_mm + 0.5
        h, w = shape_hw
        u, v = np.meshgrid(np.arange(w, dtype=float) + origin_px[0],
                           np.arange(h, dtype=float) + origin_px[1])
        xy = mapping.image_to_sheet(np.column_stack([u.ravel(), v.ravel()]))
        lo = xy.min(axis=0) - pad
        hi = xy.max(axis=0) + pad
        img, wx0, wy1 = self.window((lo[0], lo[1], hi[0], hi[1]))
        ppm = self.px_per_mm
        if blur_mm > 0:
            img = cv2.GaussianBlur(img, (0, 0), blur_mm * ppm)
        mx = ((xy[:, 0] - wx0) * ppm - 0.5).reshape(h, w).astype(np.float32)
        my = ((wy1 - xy[:, 1]) * ppm - 0.5).reshape(h, w).astype(np.float32)
        out = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        del c, half_mm
        return np.moveaxis(out, 2, 0)


def _box(p) -> tuple:
    if isinstance(p, Rect):
        return (p.x0, p.y0, p.x1, p.y1)
    if isinstance(p, Poly):
        pts = np.asarray(p.points, float)
        return (*pts.min(axis=0), *pts.max(axis=0))
    if isinstance(p, MarkerCells):
        return (p.x0, p.y0, p.x0 + p.size_mm, p.y0 + p.size_mm)
    if isinstance(p, Text):
        w = text_width_mm(p.text, p.size_mm) * 1.15 + 0.3   # the raster's font runs wider
        lo, hi = -0.35 * p.size_mm, 1.0 * p.size_mm           # descenders .. ascenders
        a = {"start": 0.0, "middle": -0.5 * w, "end": -w}[p.anchor]
        if p.angle_deg:   # reading upwards: along +y, ascenders towards -x
            return (p.x - hi, p.y + a - 0.3, p.x - lo, p.y + a + w)
        return (p.x + a - 0.3, p.y + lo, p.x + a + w, p.y + hi)
    raise TypeError(type(p).__name__)


def _kind(p, layout) -> tuple[str, str] | None:
    """(kind, label) of a non-grid primitive, None for the grid and bare paper."""
    if isinstance(p, MarkerCells):
        return "marker", f"marker {p.id}"
    if isinstance(p, Poly):
        return "arrow", "axis arrow"
    if isinstance(p, Text):
        t = p.text
        if t.lstrip("-").isdigit() or t == "mm":
            return "number", f"grid number {t!r}"
        if t.startswith("PRINT AT") or t.startswith("vision-cal sheet"):
            return "title", "title block text"
        if "bar" in t:
            return "text", f"scale bar label {t!r}"
        return "text", f"text {t!r}"
    if isinstance(p, Rect) and tuple(p.rgb) == tuple(ANNOT_RGB):
        bars = layout.bars_mm
        w, h = p.x1 - p.x0, p.y1 - p.y0
        if max(w, h) >= 50.0 and bars:
            return "scale bar", f"{'x' if w > h else 'y'} scale bar"
        return "axis", f"{'x' if w > h else 'y'} axis"
    return None


@lru_cache(maxsize=8)
def _reference_cached(key: str) -> PrintedReference | None:
    d = json.loads(key)
    pr = d["printed"]
    page = pr.get("page") or {}
    name = page.get("name")
    orient = page.get("orientation")
    landscape = None if orient == "square" else orient == "landscape"
    markers = {m["id"]: np.asarray(m["corners_mm"], float) for m in d["markers"]}
    n_side = None
    for m in markers.values():
        n_side = float(np.hypot(*(m[1] - m[0])))
        break
    module = float(pr["module_mm"])
    kw = dict(dictionary=d["aruco_dictionary"], quiet_modules=float(pr["quiet_zone_modules"]),
              measured_bar_mm=pr.get("measured_bar_mm"), version=str(pr["version"]))
    if name in (None, "custom"):
        kw["custom_mm"] = page.get("size_mm") or d["size_mm"]
        kw["landscape"] = landscape
    else:
        kw.update(size=name, landscape=landscape)
    # the marker pitch: the default, else the spacing the declared markers show
    xs = sorted({round(float(c[3][0]), 6) for c in markers.values()})
    ys = sorted({round(float(c[3][1]), 6) for c in markers.values()})
    gaps = [b - a for a, b in zip(xs, xs[1:])] + [b - a for a, b in zip(ys, ys[1:])]
    for pitch in (None, max(gaps) + 1e-7 if gaps else None):
        try:
            lay = make_layout(marker_mm=n_side, pitch_mm=pitch, **kw)
        except (VisionCalError, KeyError, TypeError, ValueError):
            continue
        if pr.get("sheet_id") not in (None, lay.sheet_id):
            continue
        if len(lay.markers) != len(markers) or not all(
                m.id in markers and np.allclose(m.corners_mm(), markers[m.id], atol=1e-4)
                for m in lay.markers):
            continue
        if abs(lay.module_mm - module) > 1e-6:
            continue
        ppm = float(pr["png_dpi"]) / 25.4 if pr.get("png_dpi") else DEFAULT_PX_PER_MM
        prims = tuple((_box(p), p) for p in lay.primitives)
        items = []
        for b, p in prims:
            k = _kind(p, lay)
            if k is not None and k[0] != "marker":
                items.append(PrintedItem(k[0], k[1], tuple(float(v) for v in b)))
        return PrintedReference(lay, ppm, tuple(items), prims)
    return None


def printed_reference(sheet: Sheet | None) -> PrintedReference | None:
    """The sheet's own print, when ``sheet.printed`` names this project's generator and the
    layout rebuilt from it matches the declared markers; else None (not described)."""
    pr = None if sheet is None else sheet.printed
    if not isinstance(pr, dict) or pr.get("generator") != GENERATOR:
        return None
    need = ("module_mm", "quiet_zone_modules", "version")
    if any(k not in pr for k in need) or not sheet.markers:
        return None
    key = json.dumps({"printed": pr, "aruco_dictionary": sheet.aruco_dictionary,
                      "size_mm": list(map(float, sheet.size_mm or ())),
                      "markers": [{"id": int(m.id), "corners_mm": np.asarray(m.corners_mm,
                                                                             float).tolist()}
                                  for m in sheet.markers]}, sort_keys=True)
    return _reference_cached(key)


def printed_content_json(sheet: Sheet | None) -> list[dict]:
    """calibration.json ``printed_content``: every printed item but the grid and the markers
    (``kind``, ``label``, ``box_mm``), for ``plan`` to say which targets lie on printed ink;
    [] for a sheet whose print is not described."""
    ref = printed_reference(sheet)
    if ref is None:
        return []
    return [{"kind": it.kind, "label": it.label, "box_mm": [round(v, 4) for v in it.box_mm]}
            for it in ref.items]


def targets_on_print(content: list[dict], ids, xy_mm, radius_mm: float) -> list[tuple]:
    """(id, labels) of the targets within ``radius_mm`` of a printed item's box."""
    out = []
    for tid, (x, y) in zip(ids, np.asarray(xy_mm, float).reshape(-1, 2)):
        near = []
        for it in content:
            x0, y0, x1, y1 = it["box_mm"]
            if math.hypot(max(x0 - x, 0.0, x - x1), max(y0 - y, 0.0, y - y1)) <= radius_mm:
                near.append(it["label"])
        if near:
            out.append((tid, near))
    return out
