"""The printable calibration sheet as pure geometry in sheet millimetres.

This module is the one owner of what ``vision-cal sheet`` prints: every writer (PDF, SVG,
PNG) draws the primitives of :class:`SheetLayout` and nothing else, and ``sheet.json`` is
derived from the same object, so the file and the print cannot disagree.

Frames and conventions
----------------------
- Sheet frame S (docs/format.md): x right, y up, mm, seen from the printed
  side. The origin is the centre of the paper (``bottom_left_mm = (-W/2, -H/2)``), which is
  also the grid origin: the grid lines sit at whole millimetres in S and the bold ones at
  multiples of 10 mm, so a mark's position can be read off the paper with a ruler.
- Marker corners follow the contract: TL, TR, BR, BL of the upright printed marker, i.e.
  with y up ``(x0, y0+s), (x0+s, y0+s), (x0+s, y0), (x0, y0)``.
- A marker is ``markerSize + 2`` modules wide (OpenCV's one-module black border around the
  dictionary's bits). Its white quiet zone (``quiet_modules`` modules on every side) is
  bare paper: neither the grid nor any print enters it.

Layout, from the paper edge inwards
-----------------------------------
``EDGE_MM`` unprinted margin (what most printers cannot reach) | quiet zone | ring of
markers around the border, evenly spaced at most ``pitch_mm`` apart with one in each
corner | quiet zone | the ruled area (grid, whole mm). Inside the ruled area a white band
along the bottom holds the x scale bar, the instruction and the title block; one along the
left holds the y scale bar; the top and right edges of the ruled area carry the numbers of
the bold lines. What is left, ``drawable_mm``, is free for the pen.

Primitives are painted in order, each opaque over what is below: :class:`Rect`,
:class:`Poly`, :class:`MarkerCells` (a marker's black modules as one union of exact
squares), :class:`Text`.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field, replace

import numpy as np

from vision_cal import __version__
from vision_cal.errors import VisionCalError

GENERATOR = "vision-cal sheet"

#: ISO 216 A sizes, portrait (width, height) in mm
ISO_SIZES_MM = {"A0": (841.0, 1189.0), "A1": (594.0, 841.0), "A2": (420.0, 594.0),
                "A3": (297.0, 420.0), "A4": (210.0, 297.0)}

# printed look (the renderer's analytic sheet, vision_cal.world.sheet, uses the same values)
PAPER_RGB = (255, 255, 255)         # no ink
FINE_RGB = (196, 228, 222)          # 1 mm lines (light cyan-green)
BOLD_RGB = (150, 205, 196)          # 10 mm lines
MARKER_RGB = (0, 0, 0)
#: bars, numbers, axes and text: a mid blue that a camera sees clearly but that darkens the
#: brightest colour channel by less than the measurer's ink threshold (30 %): no pen mark
ANNOT_RGB = (70, 120, 200)
FINE_WIDTH_MM = 0.10
BOLD_WIDTH_MM = 0.25
PITCH_MM = 1.0
BOLD_EVERY = 10

EDGE_MM = 6.0                # unprinted paper margin (beyond most printers' reach)
QUIET_MODULES = 2.0          # default white quiet zone around each marker, in modules
BAR_MM = 100.0               # scale-check bars
BAR_WIDTH_MM = 1.5
BAND_BOTTOM_MM = 14.0        # x bar, instruction, title block
BAND_LEFT_MM = 10.0          # y bar and its label
BAND_TOP_MM = 5.0            # numbers of the bold x lines
BAND_RIGHT_MM = 9.0          # numbers of the bold y lines
TEXT_MM = 2.2                # body text em size
NUMBER_MM = 2.0              # line numbers em size
MIN_MODULE_MM = 1.0          # a phone photo of a whole sheet still resolves it
MIN_DRAWABLE_MM = 20.0


# --------------------------------------------------------------------------- primitives

@dataclass(frozen=True)
class Rect:
    """Axis-aligned filled rectangle [x0, x1] x [y0, y1] (sheet mm)."""

    x0: float
    y0: float
    x1: float
    y1: float
    rgb: tuple[int, int, int]


@dataclass(frozen=True)
class Poly:
    """Filled polygon, points (N, 2) sheet mm."""

    points: tuple[tuple[float, float], ...]
    rgb: tuple[int, int, int]


@dataclass(frozen=True)
class MarkerCells:
    """One marker: ``bits`` (n, n) 1 = black module, row 0 at the top (as OpenCV draws it),
    lower-left corner ``(x0, y0)``, module side ``module_mm``."""

    id: int
    x0: float
    y0: float
    module_mm: float
    bits: np.ndarray = field(compare=False)

    @property
    def size_mm(self) -> float:
        return self.module_mm * self.bits.shape[0]

    def cells(self):
        """Black modules as (x0, y0, x1, y1) squares in sheet mm."""
        n = self.bits.shape[0]
        m = self.module_mm
        for r in range(n):
            for c in range(n):
                if self.bits[r, c]:
                    y_top = self.y0 + (n - r) * m
                    yield (self.x0 + c * m, y_top - m, self.x0 + (c + 1) * m, y_top)

    def corners_mm(self) -> np.ndarray:
        s = self.size_mm
        x0, y0 = self.x0, self.y0
        return np.array([[x0, y0 + s], [x0 + s, y0 + s], [x0 + s, y0], [x0, y0]])


@dataclass(frozen=True)
class Text:
    """A line of text; baseline starts (``start``), is centred (``middle``) or ends
    (``end``) at (x, y); ``size_mm`` the em size; ``angle_deg`` 0 or 90 (reading upwards)."""

    x: float
    y: float
    text: str
    size_mm: float
    rgb: tuple[int, int, int] = ANNOT_RGB
    anchor: str = "start"
    angle_deg: float = 0.0


# --------------------------------------------------------------------------- the layout

@dataclass(frozen=True)
class SheetLayout:
    """Everything printed on the sheet (see the module docstring).

    ``markers`` in id order; ``primitives`` in paint order; ``bars_mm`` {"x": (start, end),
    "y": (start, end)} the measured edges of the scale bars (their ends), sheet mm;
    ``grid_extent_mm`` / ``drawable_mm`` (x0, y0, x1, y1).
    """

    page: str
    orientation: str
    size_mm: tuple[float, float]
    bottom_left_mm: tuple[float, float]
    dictionary: str
    module_mm: float
    quiet_modules: float
    markers: tuple[MarkerCells, ...]
    grid_extent_mm: tuple[float, float, float, float]
    drawable_mm: tuple[float, float, float, float]
    bars_mm: dict
    primitives: tuple
    version: str
    measured_bar_mm: tuple[float, float] | None = None

    @property
    def marker_mm(self) -> float:
        return self.markers[0].size_mm

    @property
    def extent_mm(self) -> tuple[float, float, float, float]:
        x0, y0 = self.bottom_left_mm
        return (x0, y0, x0 + self.size_mm[0], y0 + self.size_mm[1])

    @property
    def sheet_id(self) -> str:
        """Short content hash of the printed geometry: equal ids, equal sheets."""
        key = json.dumps([self.dictionary, _r(self.size_mm), _r(self.bottom_left_mm),
                          _r(self.quiet_modules),
                          [[m.id, _r(m.corners_mm().tolist())] for m in self.markers]])
        return hashlib.sha256(key.encode()).hexdigest()[:8]

    def quiet_boxes_mm(self) -> np.ndarray:
        """(M, 4) [x0, y0, x1, y1] of each marker with its quiet zone."""
        q = self.quiet_modules * self.module_mm
        return np.array([[m.x0 - q, m.y0 - q, m.x0 + m.size_mm + q, m.y0 + m.size_mm + q]
                         for m in self.markers])

    def to_sheet_json(self) -> dict:
        """The session's ``sheet`` block (docs/format.md), with ``bottom_left_mm``,
        ``grid`` and ``printed``."""
        printed = {
            "module_mm": _r(self.module_mm),
            "quiet_zone_modules": _r(self.quiet_modules),
            "quiet_zone_mm": _r(self.quiet_modules * self.module_mm),
            "border_modules": 1,
            "page": {"name": self.page, "orientation": self.orientation,
                     "size_mm": _r(list(self.size_mm))},
            "generator": GENERATOR,
            "version": self.version,
            "sheet_id": self.sheet_id,
            "drawable_mm": _r(list(self.drawable_mm)),
            "scale_bars_mm": {k: _r([list(p) for p in v]) for k, v in self.bars_mm.items()},
            "scale_bar_length_mm": BAR_MM,
        }
        if self.measured_bar_mm is not None:
            printed["measured_bar_mm"] = [float(v) for v in self.measured_bar_mm]
        return {
            "aruco_dictionary": self.dictionary,
            "markers": [{"id": m.id, "corners_mm": _r(m.corners_mm().tolist())}
                        for m in self.markers],
            "size_mm": _r(list(self.size_mm)),
            "bottom_left_mm": _r(list(self.bottom_left_mm)),
            "grid": {"pitch_mm": PITCH_MM, "bold_every": BOLD_EVERY, "origin_mm": [0.0, 0.0],
                     "fine_width_mm": FINE_WIDTH_MM, "bold_width_mm": BOLD_WIDTH_MM,
                     "extent_mm": _r(list(self.grid_extent_mm))},
            "printed": printed,
        }


def _r(v, nd: int = 6):
    """Round floats (nested lists) to ``nd`` decimals for the JSON (1 nm: exact enough)."""
    if isinstance(v, (list, tuple)):
        return [_r(x, nd) for x in v]
    v = round(float(v), nd)
    return 0.0 if v == 0 else v


#: the JSON rounding of every layout's sheet.json (the ChArUco board's too)
rounded = _r


# --------------------------------------------------------------------------- page sizes

#: the largest custom page side (mm): the largest SCARA reaches about 1 m, so its whole work
#: area fits in 2 m; 5 m leaves room and keeps the SVG and PDF a few MB (1e6 mm wrote 154 MB)
MAX_PAGE_MM = 5000.0


def page_size_mm(size: str | None = "A3", *, landscape: bool | None = None,
                 custom_mm=None) -> tuple[str, str, tuple[float, float]]:
    """(page name, orientation, (width, height) mm) from an ISO name or a custom size.

    ISO sheets default to landscape (a SCARA's reach is wider than deep); a custom size is
    taken as given unless ``landscape`` is set, which swaps it as needed.
    """
    if custom_mm is not None:
        w, h = (float(v) for v in custom_mm)
        if not (math.isfinite(w) and math.isfinite(h)) or w <= 0 or h <= 0:
            raise VisionCalError(f"expected two positive sizes in mm, got {custom_mm!r}",
                                 field="--custom")
        if max(w, h) > MAX_PAGE_MM:
            raise VisionCalError(f"expected sides of at most {MAX_PAGE_MM:g} mm (no plotter "
                                 f"roll or SCARA work area is wider), got {w:g} x {h:g} mm",
                                 field="--custom")
        name = "custom"
    else:
        key = str(size).upper()
        if key not in ISO_SIZES_MM:
            raise VisionCalError(f"expected one of {', '.join(sorted(ISO_SIZES_MM))}, got "
                                 f"{size!r}", field="--size")
        w, h = ISO_SIZES_MM[key]
        name = key
        if landscape is None:
            landscape = True
    if landscape is not None and (w > h) != bool(landscape) and w != h:
        w, h = h, w
    orientation = "landscape" if w > h else ("portrait" if h > w else "square")
    return name, orientation, (w, h)


def aruco_dictionary(name: str):
    # OpenCV takes 0.2 s to import: loaded here, when used
    import cv2

    d = getattr(cv2.aruco, str(name), None)
    if not str(name).startswith("DICT_") or not isinstance(d, int):
        raise VisionCalError(f"unknown OpenCV ArUco dictionary {name!r} (expected a name like "
                             "DICT_5X5_100)", field="--dictionary")
    return cv2.aruco.getPredefinedDictionary(d)


def marker_bits(dictionary: str, marker_id: int) -> np.ndarray:
    """(n, n) uint8, 1 = black, of one marker with its one-module black border (row 0 top),
    straight from OpenCV's dictionary (``generateImageMarker`` at one pixel per module)."""
    # OpenCV takes 0.2 s to import: loaded here, when used
    import cv2

    d = aruco_dictionary(dictionary)
    n = int(d.markerSize) + 2
    img = cv2.aruco.generateImageMarker(d, int(marker_id), n, borderBits=1)
    return (np.asarray(img) < 128).astype(np.uint8)


def default_module_mm(short_side_mm: float, n_cells: int) -> float:
    """Module size giving markers about 1/15 of the short side, on a 0.25 mm step."""
    return max(MIN_MODULE_MM, round(short_side_mm / 15.0 / n_cells * 4.0) / 4.0)


def _ring_positions(lo: float, hi: float, pitch: float) -> np.ndarray:
    """Evenly spaced positions from lo to hi (both included), at most ``pitch`` apart."""
    span = hi - lo
    n = max(int(math.ceil(span / pitch - 1e-9)), 1) + 1
    return lo + span * np.arange(n) / (n - 1)


def _sizes(n_cells: int, short_mm: float, marker_mm, pitch_mm, quiet_modules,
           measured_bar_mm) -> tuple[float, float, float, float, tuple | None]:
    """The options checked, as ``(module, side, quiet, pitch, measured_bar_mm)`` in mm.
    Refuses (``VisionCalError`` naming the option) a non-positive marker, a negative quiet
    zone, a pitch smaller than a marker with its quiet zones, or bars far from 100 mm."""
    if marker_mm is None:
        module = default_module_mm(short_mm, n_cells)
    else:
        if not (math.isfinite(marker_mm) and marker_mm > 0):
            raise VisionCalError(f"expected a positive size, got {marker_mm!r}",
                                 field="--marker-mm")
        module = float(marker_mm) / n_cells
    if not (math.isfinite(quiet_modules) and quiet_modules >= 0):
        raise VisionCalError(f"expected a non-negative number, got {quiet_modules!r}",
                             field="quiet_modules")
    s = module * n_cells
    q = quiet_modules * module
    if pitch_mm is None:
        pitch = 4.0 * s
    else:
        pitch = float(pitch_mm)
        if not (math.isfinite(pitch) and pitch >= s + 2 * q):
            raise VisionCalError(f"expected at least a marker and its quiet zones "
                                 f"({s + 2 * q:g} mm), got {pitch_mm!r}", field="--pitch-mm")
    if measured_bar_mm is not None:
        mb = [float(v) for v in measured_bar_mm]
        if len(mb) != 2 or not all(math.isfinite(v) and 50.0 < v < 200.0 for v in mb):
            raise VisionCalError(f"expected the two printed bars' lengths in mm (about 100), "
                                 f"got {measured_bar_mm!r}", field="--measured-bar-mm")
        measured_bar_mm = (mb[0], mb[1])
    return module, s, q, pitch, measured_bar_mm


def _areas(W: float, H: float, s: float, q: float, field: str) -> tuple[tuple, tuple]:
    """The ruled area ``(gx0, gy0, gx1, gy1)`` (whole mm inside the quiet zones' inner
    edges) and the drawable area ``(dx0, dy0, dx1, dy1)`` (inside the bands); refuses, naming
    ``field``, a page whose drawable area cannot hold the scale bars."""
    x_min, y_min = -W / 2.0, -H / 2.0
    x_max, y_max = W / 2.0, H / 2.0
    r = EDGE_MM + q + s + q               # paper edge -> inner edge of the quiet zones
    hw = BOLD_WIDTH_MM / 2                # a line's half width stays off the quiet zone
    gx0, gy0 = math.ceil(x_min + r + hw), math.ceil(y_min + r + hw)
    gx1, gy1 = math.floor(x_max - r - hw), math.floor(y_max - r - hw)
    dx0, dy0 = gx0 + BAND_LEFT_MM, gy0 + BAND_BOTTOM_MM
    dx1, dy1 = gx1 - BAND_RIGHT_MM, gy1 - BAND_TOP_MM
    need = BAR_MM + 2.0
    if dx1 - dx0 < max(need, MIN_DRAWABLE_MM) or dy1 - dy0 < max(need, MIN_DRAWABLE_MM):
        raise VisionCalError(f"a {W:g} x {H:g} mm page with {s:g} mm markers leaves "
                             f"{dx1 - dx0:g} x {dy1 - dy0:g} mm inside the markers; the "
                             f"{BAR_MM:g} mm scale bars need {need:g} mm", field=field)
    return (gx0, gy0, gx1, gy1), (dx0, dy0, dx1, dy1)


def _ring(W: float, H: float, module: float, s: float, q: float, pitch: float,
          dictionary: str, n_ids: int) -> tuple[MarkerCells, ...]:
    """The ring of markers, ids counter-clockwise from the bottom-left corner; refuses more
    markers than the dictionary holds, or markers closer than their quiet zones."""
    e = EDGE_MM + q                       # paper edge -> marker edge
    xs = _ring_positions(-W / 2.0 + e, W / 2.0 - e - s, pitch)
    ys = _ring_positions(-H / 2.0 + e, H / 2.0 - e - s, pitch)
    spots = ([(x, ys[0]) for x in xs] + [(xs[-1], y) for y in ys[1:]]
             + [(x, ys[-1]) for x in xs[-2::-1]] + [(xs[0], y) for y in ys[-2:0:-1]])
    if len(spots) > n_ids:
        raise VisionCalError(f"the page needs {len(spots)} markers but {dictionary} has only "
                             f"{n_ids}; choose a larger --pitch-mm or dictionary",
                             field="--dictionary")
    gap = min(np.diff(xs).min() if len(xs) > 1 else np.inf,
              np.diff(ys).min() if len(ys) > 1 else np.inf)
    if gap < s + 2 * q - 1e-9:
        raise VisionCalError("markers too close together for their quiet zones",
                             field="--pitch-mm")
    return tuple(MarkerCells(i, float(x), float(y), module, marker_bits(dictionary, i))
                 for i, (x, y) in enumerate(spots))


def _grid_prims(ruled: tuple, drawable: tuple) -> list:
    """The grid (whole millimetres from the origin, inside the ruled area, the bold lines
    over the fine ones), then the bare-paper bands for the bars and the text."""
    gx0, gy0, gx1, gy1 = ruled
    dx0, dy0 = drawable[:2]
    prims: list = []
    for bold, width, rgb in ((False, FINE_WIDTH_MM, FINE_RGB), (True, BOLD_WIDTH_MM, BOLD_RGB)):
        w = width / 2
        prims += [Rect(k - w, gy0, k + w, gy1, rgb) for k in grid_lines(gx0, gx1, bold)]
        prims += [Rect(gx0, k - w, gx1, k + w, rgb) for k in grid_lines(gy0, gy1, bold)]
    prims.append(Rect(gx0 - 1, gy0 - 1, gx1 + 1, dy0, PAPER_RGB))
    prims.append(Rect(gx0 - 1, dy0, dx0, gy1 + 1, PAPER_RGB))
    return prims


def _bar_prims(drawable: tuple) -> tuple[list, dict, float]:
    """The scale bars (x along the bottom band, y along the left band) with their labels,
    the bars' measured ends ``{"x": (start, end), "y": ...}`` and the x bar's bottom edge."""
    dx0, dy0 = drawable[:2]
    by = dy0 - 3.0 - BAR_WIDTH_MM
    bar_x = Rect(dx0, by, dx0 + BAR_MM, by + BAR_WIDTH_MM, ANNOT_RGB)
    bx = dx0 - 3.0 - BAR_WIDTH_MM
    bar_y = Rect(bx, dy0, bx + BAR_WIDTH_MM, dy0 + BAR_MM, ANNOT_RGB)
    yc, xc = by + BAR_WIDTH_MM / 2, bx + BAR_WIDTH_MM / 2
    bars = {"x": ((dx0, yc), (dx0 + BAR_MM, yc)), "y": ((xc, dy0), (xc, dy0 + BAR_MM))}
    prims = [bar_x, bar_y,
             Text(dx0 + BAR_MM + 2.0, by + 0.2, f"<- x bar {BAR_MM:.1f} mm", TEXT_MM),
             Text(bx - 0.8, dy0 + BAR_MM + 2.0, f"y bar {BAR_MM:.1f} mm ->",
                  TEXT_MM, angle_deg=90.0)]
    return prims, bars, by


def _axes_prims(drawable: tuple) -> list:
    """The origin (the paper centre) and the axes; the letters x and y only when the
    drawable area holds them."""
    dx0, dy0, dx1, dy1 = drawable
    ax = 12.0
    t = 0.35
    prims = [Rect(0.0, -t / 2, ax, t / 2, ANNOT_RGB), Rect(-t / 2, 0.0, t / 2, ax, ANNOT_RGB),
             Poly(((ax, -1.0), (ax + 3.0, 0.0), (ax, 1.0)), ANNOT_RGB),
             Poly(((-1.0, ax), (0.0, ax + 3.0), (1.0, ax)), ANNOT_RGB),
             Text(ax + 3.8, -0.8, "x", 3.0, anchor="start"),
             Text(0.0, ax + 4.0, "y", 3.0, anchor="middle"),
             Text(-1.0, -3.2, "origin (0, 0)", NUMBER_MM, anchor="end")]
    if not (dx0 < -1 and dx1 > ax + 6 and dy0 < -4 and dy1 > ax + 6):
        prims = [p for p in prims if not (isinstance(p, Text) and p.text in "xy")]
    return prims


def _number_labels(prims: list, ruled: tuple, drawable: tuple) -> None:
    """Numbers of the bold lines into ``prims``: x along the top of the ruled area, y along
    its right side, and the unit."""
    gx1, gy1 = ruled[2:]
    dx0, dy0, dx1, dy1 = drawable
    for k in range(int(math.ceil(dx0 / BOLD_EVERY)) * BOLD_EVERY, int(dx1) + 1, BOLD_EVERY):
        _label(prims, Text(float(k), gy1 - NUMBER_MM - 0.6, f"{k}", NUMBER_MM, anchor="middle"))
    for k in range(int(math.ceil(dy0 / BOLD_EVERY)) * BOLD_EVERY, int(dy1) + 1, BOLD_EVERY):
        _label(prims, Text(gx1 - 0.8, k - 0.35 * NUMBER_MM, f"{k}", NUMBER_MM, anchor="end"))
    _label(prims, Text(gx1 - 0.8, gy1 - NUMBER_MM - 0.6, "mm", NUMBER_MM, anchor="end"))


def _title_prims(layout: SheetLayout, s: float, by: float) -> list:
    """The instruction and title block, under the x bar, each line fitted to the ruled
    area's width."""
    W, H = layout.size_mm
    lines = [f"PRINT AT 100 % (actual size, no fit-to-page). Measure both bars: each must be "
             f"{BAR_MM:.1f} mm. If not, give vision-cal sheet --measured-bar-mm X Y.",
             f"vision-cal sheet {layout.sheet_id} | {layout.dictionary}, {len(layout.markers)} "
             f"markers of {s:g} mm (module {layout.module_mm:g} mm, quiet zone "
             f"{layout.quiet_modules:g} modules) | {layout.page} {layout.orientation} "
             f"{W:g} x {H:g} mm | origin at the centre | {GENERATOR} {layout.version}"]
    dx0, gx1 = layout.drawable_mm[0], layout.grid_extent_mm[2]
    width = gx1 - dx0
    return [Text(dx0, by - 3.2 - i * (TEXT_MM + 1.0), line, min(TEXT_MM, _fit_size(line, width)))
            for i, line in enumerate(lines)]


def make_layout(*, size: str | None = "A3", landscape: bool | None = None, custom_mm=None,
                dictionary: str = "DICT_5X5_100", marker_mm: float | None = None,
                pitch_mm: float | None = None, quiet_modules: float = QUIET_MODULES,
                measured_bar_mm=None, version: str | None = None) -> SheetLayout:
    """The sheet for a page (ISO ``size`` or ``custom_mm``), see the module docstring.

    ``marker_mm``: side of a marker including its black border (default about 1/15 of the
    short side); ``pitch_mm``: the largest centre-to-centre spacing of the border markers
    (default 4 marker sides); ``quiet_modules``: the white margin around each marker.
    Refuses (``VisionCalError`` naming the option) what does not fit.
    """
    version = __version__ if version is None else version
    page, orientation, (W, H) = page_size_mm(size, landscape=landscape, custom_mm=custom_mm)
    d = aruco_dictionary(dictionary)
    n_cells = int(d.markerSize) + 2
    module, s, q, pitch, measured_bar_mm = _sizes(n_cells, min(W, H), marker_mm, pitch_mm,
                                                  quiet_modules, measured_bar_mm)
    field = "--marker-mm" if marker_mm is not None else ("--custom" if custom_mm is not None
                                                         else "--size")
    ruled, drawable = _areas(W, H, s, q, field)
    markers = _ring(W, H, module, s, q, pitch, dictionary, int(d.bytesList.shape[0]))

    prims = _grid_prims(ruled, drawable)
    bar_prims, bars, by = _bar_prims(drawable)
    prims += bar_prims
    prims += _axes_prims(drawable)
    _number_labels(prims, ruled, drawable)
    # markers (painted after the grid and the bands: their quiet zones are bare paper)
    for (qx0, qy0, qx1, qy1) in _quiet_boxes(markers, q):
        prims.append(Rect(qx0, qy0, qx1, qy1, PAPER_RGB))
    prims.extend(markers)

    layout = SheetLayout(page, orientation, (W, H), (-W / 2.0, -H / 2.0), str(dictionary),
                         module, float(quiet_modules), markers, ruled, drawable, bars, (),
                         str(version), measured_bar_mm)
    prims += _title_prims(layout, s, by)
    return with_primitives(layout, tuple(prims))


def grid_lines(lo: int, hi: int, bold: bool) -> list[int]:
    """Whole-mm positions lo..hi of the bold (every ``BOLD_EVERY`` mm) or the fine lines."""
    return [k for k in range(int(lo), int(hi) + 1) if (k % BOLD_EVERY == 0) == bold]


def _quiet_boxes(markers, q):
    return [(m.x0 - q, m.y0 - q, m.x0 + m.size_mm + q, m.y0 + m.size_mm + q) for m in markers]


def _label(prims: list, t: Text) -> None:
    """A number on a white box (so that the grid line does not run through it)."""
    w = text_width_mm(t.text, t.size_mm)
    x0 = {"start": t.x, "middle": t.x - w / 2, "end": t.x - w}[t.anchor]
    prims.append(Rect(x0 - 0.3, t.y - 0.3 * t.size_mm, x0 + w + 0.3, t.y + 0.85 * t.size_mm,
                      PAPER_RGB))
    prims.append(t)


def text_width_mm(text: str, size_mm: float) -> float:
    """Width of ``text`` in Helvetica (the PDF's font) at em size ``size_mm``."""
    # reportlab's PDF machinery: loaded here, when a PDF is drawn
    from reportlab.pdfbase.pdfmetrics import stringWidth

    return float(stringWidth(text, "Helvetica", size_mm))


def _fit_size(text: str, width_mm: float) -> float:
    return width_mm / max(text_width_mm(text, 1.0), 1e-9)


def with_primitives(layout: SheetLayout, prims: tuple) -> SheetLayout:
    return replace(layout, primitives=prims)
