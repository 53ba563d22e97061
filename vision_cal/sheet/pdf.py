"""The sheet as a vector PDF at true scale.

Why reportlab: it is a well-kept, pure-Python PDF writer that takes the page size in
points and draws paths in any user unit, so one ``scale(72 / 25.4)`` makes every
coordinate a millimetre of the sheet frame (y up, as in PDF) with no raster anywhere;
matplotlib's PDF backend would route the geometry through figure/axes transforms and
snap or pad it. The page is exactly the paper, and ``PrintScaling = None`` asks viewers
to print it at 100 %.

Each marker's black modules are one filled path (a union of exact squares), so a
rasteriser draws no seams between neighbouring modules; consecutive rectangles of one
colour (the grid lines, the two scale bars) are one path too. Besides being smaller, a
compound path is anti-aliased at its true edges by pdfium (Chrome's PDF engine, which
many users print from), whereas a lone rectangle is snapped outwards to whole device
pixels: up to 0.04 mm per edge on a 600 dpi printer.
"""

from __future__ import annotations

import math
from io import BytesIO

from vision_cal.sheet.layout import MarkerCells, Poly, Rect, SheetLayout, Text

PT_PER_MM = 72.0 / 25.4


def _page_pt(size_mm: float) -> float:
    """The page side in points, rounded *down* to 0.01 pt (< 3.6 um
    short of the paper; the drawing itself is at exact scale). Rounded up, a rasteriser
    that fits the page to whole pixels (pdfium) would add a pixel and stretch the page by
    1/N (0.03 % at 6 px/mm on A2)."""
    return math.floor(size_mm * PT_PER_MM * 100.0 + 1e-9) / 100.0


def _runs(prims):
    """Primitives with consecutive same-coloured ``Rect`` grouped into lists."""
    out: list = []
    for p in prims:
        if isinstance(p, Rect) and out and isinstance(out[-1], list) and out[-1][0].rgb == p.rgb:
            out[-1].append(p)
        else:
            out.append([p] if isinstance(p, Rect) else p)
    return out


def pdf_bytes(layout: SheetLayout) -> bytes:
    # reportlab's PDF machinery: loaded here, when a PDF is drawn
    from reportlab.pdfgen import canvas

    W, H = layout.size_mm
    x_min, y_min = layout.bottom_left_mm
    buf = BytesIO()
    c = canvas.Canvas(buf, pagesize=(_page_pt(W), _page_pt(H)), invariant=1,
                      pageCompression=1)
    c.setTitle(f"vision-cal sheet {layout.sheet_id}")
    c.setAuthor("vision-cal")
    c.setSubject(f"{layout.dictionary} calibration sheet, {layout.page} {layout.orientation}; "
                 "print at 100 %")
    c.setViewerPreference("PrintScaling", "None")
    c.scale(PT_PER_MM, PT_PER_MM)
    c.translate(-x_min, -y_min)           # user units: sheet mm, origin of frame S
    for p in _runs(layout.primitives):
        if isinstance(p, list):                      # rectangles of one colour
            c.setFillColorRGB(*(v / 255.0 for v in p[0].rgb))
            path = c.beginPath()
            for r in p:
                path.rect(r.x0, r.y0, r.x1 - r.x0, r.y1 - r.y0)
            c.drawPath(path, stroke=0, fill=1, fillMode=0)
        elif isinstance(p, Poly):
            c.setFillColorRGB(*(v / 255.0 for v in p.rgb))
            path = c.beginPath()
            (x, y), *rest = p.points
            path.moveTo(x, y)
            for x, y in rest:
                path.lineTo(x, y)
            path.close()
            c.drawPath(path, stroke=0, fill=1)
        elif isinstance(p, MarkerCells):
            c.setFillColorRGB(0, 0, 0)
            path = c.beginPath()
            for x0, y0, x1, y1 in p.cells():
                path.rect(x0, y0, x1 - x0, y1 - y0)
            c.drawPath(path, stroke=0, fill=1, fillMode=0)   # nonzero winding: the union
        elif isinstance(p, Text):
            c.saveState()
            c.setFillColorRGB(*(v / 255.0 for v in p.rgb))
            c.setFont("Helvetica", p.size_mm)
            c.translate(p.x, p.y)
            if p.angle_deg:
                c.rotate(p.angle_deg)
            draw = {"start": c.drawString, "middle": c.drawCentredString,
                    "end": c.drawRightString}[p.anchor]
            draw(0, 0, p.text)
            c.restoreState()
        else:  # pragma: no cover - a new primitive without a writer
            raise TypeError(f"no PDF writer for {type(p).__name__}")
    c.showPage()
    c.save()
    return buf.getvalue()
