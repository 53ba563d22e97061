"""The sheet as SVG: the same primitives, width and height in mm, one user unit = 1 mm.

SVG's y axis points down: a sheet point (x, y) is drawn at (x - x_min, y_max - y).
"""

from __future__ import annotations

from xml.sax.saxutils import escape

from vision_cal.sheet.layout import MarkerCells, Poly, Rect, SheetLayout, Text


def _f(v: float) -> str:
    s = f"{v:.6f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def _rgb(c) -> str:
    return "#{:02x}{:02x}{:02x}".format(*(int(v) for v in c))


def svg_text(layout: SheetLayout) -> str:
    W, H = layout.size_mm
    x_min, y_min, _, y_max = layout.extent_mm
    X = lambda x: _f(x - x_min)          # noqa: E731
    Y = lambda y: _f(y_max - y)          # noqa: E731
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           f'<svg xmlns="http://www.w3.org/2000/svg" width="{_f(W)}mm" height="{_f(H)}mm" '
           f'viewBox="0 0 {_f(W)} {_f(H)}">',
           f'<title>vision-cal sheet {layout.sheet_id} ({escape(layout.dictionary)}, '
           f'{layout.page} {layout.orientation}); print at 100 %</title>',
           f'<rect x="0" y="0" width="{_f(W)}" height="{_f(H)}" fill="#ffffff"/>']
    for p in layout.primitives:
        if isinstance(p, Rect):
            out.append(f'<rect x="{X(p.x0)}" y="{Y(p.y1)}" width="{_f(p.x1 - p.x0)}" '
                       f'height="{_f(p.y1 - p.y0)}" fill="{_rgb(p.rgb)}"/>')
        elif isinstance(p, Poly):
            pts = " ".join(f"{X(x)},{Y(y)}" for x, y in p.points)
            out.append(f'<polygon points="{pts}" fill="{_rgb(p.rgb)}"/>')
        elif isinstance(p, MarkerCells):
            d = "".join(f"M{X(x0)} {Y(y1)}h{_f(x1 - x0)}v{_f(y1 - y0)}h{_f(x0 - x1)}z"
                        for x0, y0, x1, y1 in p.cells())
            out.append(f'<path id="marker{p.id}" d="{d}" fill="#000000" fill-rule="nonzero"/>')
        elif isinstance(p, Text):
            anchor = {"start": "start", "middle": "middle", "end": "end"}[p.anchor]
            rot = (f' transform="rotate({_f(-p.angle_deg)} {X(p.x)} {Y(p.y)})"'
                   if p.angle_deg else "")
            out.append(f'<text x="{X(p.x)}" y="{Y(p.y)}" font-family="Helvetica, Arial, '
                       f'sans-serif" font-size="{_f(p.size_mm)}" text-anchor="{anchor}" '
                       f'fill="{_rgb(p.rgb)}"{rot}>{escape(p.text)}</text>')
        else:  # pragma: no cover
            raise TypeError(f"no SVG writer for {type(p).__name__}")
    out.append("</svg>")
    return "\n".join(out) + "\n"
