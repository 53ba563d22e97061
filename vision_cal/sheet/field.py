"""The marker field: a sheet a camera on the arm sees piecewise (``vision-cal sheet --field``).

An ArUco grid over the whole page rather than a ChArUco board: every marker names itself,
so a view holding any 2 of them (often partly hidden by the arm or cut by the image edge)
gives its pose with no board-wide corner indexing, and the measurement stage's own
detector and sub-pixel edge fit (``measure/aruco.py``) read it unchanged. A ChArUco board's
chessboard corners are a little more precise per corner, but need a second corner
pipeline; the field's markers give 4 corners each from 4 fitted edges.

The markers sit on a regular grid, ``pitch_mm`` apart (default 2 marker sides, so any view
of 100 x 75 mm holds at least 2 whole markers), each with its quiet zone. No ruled grid
(there are no pen marks to read against it), and no scale bars: sheet.json's ``printed``
says so (``kind: field``). Shares the ring sheet's primitives and writers
(:mod:`vision_cal.sheet.layout`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


from vision_cal import __version__
from vision_cal.errors import VisionCalError
from vision_cal.sheet.layout import (EDGE_MM, QUIET_MODULES, TEXT_MM, GENERATOR, MarkerCells,
                                     Rect, SheetLayout, Text, PAPER_RGB, aruco_dictionary,
                                     with_primitives, marker_bits, page_size_mm)

#: default marker side (mm) and pitch (in marker sides) of a field
FIELD_MARKER_MM = 18.0
FIELD_PITCH_SIDES = 2.0


@dataclass(frozen=True)
class FieldLayout(SheetLayout):
    """A :class:`SheetLayout` whose sheet.json has no printed grid and no scale bars."""

    def to_sheet_json(self) -> dict:
        d = super().to_sheet_json()
        d.pop("grid", None)
        p = d["printed"]
        for k in ("scale_bars_mm", "scale_bar_length_mm"):
            p.pop(k, None)
        p["kind"] = "field"
        return d


def make_field_layout(*, size: str | None = "A3", landscape: bool | None = None,
                      custom_mm=None, dictionary: str = "DICT_5X5_1000",
                      marker_mm: float | None = None, pitch_mm: float | None = None,
                      quiet_modules: float = QUIET_MODULES,
                      version: str | None = None) -> FieldLayout:
    """Markers on a grid over the whole page; ids row by row from the bottom left."""
    version = __version__ if version is None else version
    page, orientation, (W, H) = page_size_mm(size, landscape=landscape, custom_mm=custom_mm)
    d = aruco_dictionary(dictionary)
    n_cells = int(d.markerSize) + 2
    s = FIELD_MARKER_MM if marker_mm is None else float(marker_mm)
    if not (math.isfinite(s) and s > 0):
        raise VisionCalError(f"expected a positive size, got {marker_mm!r}", field="--marker-mm")
    module = s / n_cells
    q = quiet_modules * module
    pitch = FIELD_PITCH_SIDES * s if pitch_mm is None else float(pitch_mm)
    if not (math.isfinite(pitch) and pitch >= s + 2 * q):
        raise VisionCalError(f"expected at least a marker and its quiet zones ({s + 2 * q:g} "
                             f"mm), got {pitch_mm!r}", field="--pitch-mm")
    x_min, y_min = -W / 2.0, -H / 2.0
    e = EDGE_MM + q
    bottom = e + TEXT_MM + 3.0                 # room for the title line under the field
    nx = int(math.floor((W - 2 * e - s) / pitch)) + 1
    ny = int(math.floor((H - e - bottom - s) / pitch)) + 1
    if nx < 2 or ny < 2:
        raise VisionCalError(f"a {W:g} x {H:g} mm page holds {nx} x {ny} markers of {s:g} mm "
                             f"at {pitch:g} mm: at least 2 x 2 are needed", field="--marker-mm")
    if nx * ny > int(d.bytesList.shape[0]):
        raise VisionCalError(f"the field needs {nx * ny} markers but {dictionary} has only "
                             f"{int(d.bytesList.shape[0])}; choose a larger --pitch-mm or "
                             "dictionary", field="--dictionary")
    x0 = x_min + (W - (nx - 1) * pitch - s) / 2.0
    y0 = y_min + bottom + (H - e - bottom - (ny - 1) * pitch - s) / 2.0
    markers = tuple(MarkerCells(r * nx + c, float(x0 + c * pitch), float(y0 + r * pitch),
                                module, marker_bits(dictionary, r * nx + c))
                    for r in range(ny) for c in range(nx))
    prims: list = []
    for m in markers:
        prims.append(Rect(m.x0 - q, m.y0 - q, m.x0 + s + q, m.y0 + s + q, PAPER_RGB))
    prims.extend(markers)
    ext = (x_min, y_min, x_min + W, y_min + H)
    layout = FieldLayout(page, orientation, (W, H), (x_min, y_min), str(dictionary), module,
                         float(quiet_modules), markers, ext, ext, {}, (), str(version), None)
    line = (f"PRINT AT 100 % (actual size). vision-cal sheet --field {layout.sheet_id} | "
            f"{dictionary}, {len(markers)} markers of {s:g} mm every {pitch:g} mm | {page} "
            f"{orientation} {W:g} x {H:g} mm | origin at the centre | {GENERATOR} {version}")
    prims.append(Text(x_min + e, y_min + EDGE_MM + 0.5, line,
                      min(TEXT_MM, 0.9 * (W - 2 * e) / max(len(line) * 0.55, 1.0))))
    return with_primitives(layout, tuple(prims))
