"""The printed calibration sheet: ArUco layout and its texture image.

Frames and conventions
----------------------
- Sheet frame S: x right, y up, millimetres, seen from above (the side the pen draws on).
  ``Sheet.extent_mm`` = (x_min, y_min, x_max, y_max) of the paper.
- Marker corners follow the dataset format: TL, TR, BR, BL of the upright printed marker,
  i.e. with y up ``(x0, y0+s), (x0+s, y0+s), (x0+s, y0), (x0, y0)``.
- Texture pixels: the texture is an (H, W, 3) uint8 RGB image of the paper, row 0 at the top
  (y = y_max), H = size_y * px_per_mm, W = size_x * px_per_mm (both must be whole numbers).
  Pixel (row i, col j) has its centre at

      x = x_min + (j + 0.5) / px_per_mm,     y = y_max - (i + 0.5) / px_per_mm

  and covers the square of side 1/px_per_mm around it. ``sheet_to_texture_pixel`` converts
  sheet mm to OpenCV-style texture pixel coordinates (u, v) = (col, row), integer at pixel
  centres.

Photometry (so that a measurement can rely on it)
-------------------------------------------------
Every printed layer is drawn with exact area-coverage anti-aliasing: grid lines and marker
modules are axis-aligned rectangles whose pixel coverage is computed analytically
(separable 1-D overlaps); ink dots are ellipses sampled at least 12 x 12 per pixel (and 160 samples
across the dot) inside their bounding box only. Printed ink (grid, markers) multiplies the paper colour by its
transmittance ``1 - coverage * (1 - ink/255)``; pen dots are opaque and alpha-blend the
``DOT_RGB`` colour over whatever is below with alpha = coverage. The centroid of every
dot's coverage is its mark (the ellipse is centred on it).
"""

from __future__ import annotations

import cv2
import numpy as np

from vision_cal.dataset.session import Sheet, SheetGrid, SheetMarker
from vision_cal.errors import VisionCalError

PAPER_RGB = (247.0, 245.0, 238.0)   # off-white paper
FINE_RGB = (196.0, 228.0, 222.0)    # 1 mm plotting-paper lines (light cyan-green)
BOLD_RGB = (150.0, 205.0, 196.0)    # 10 mm lines
MARKER_RGB = (18.0, 18.0, 18.0)     # printed ArUco black
DOT_RGB = (28.0, 32.0, 92.0)        # pen ink (dark blue)
FINE_WIDTH_MM = 0.10
BOLD_WIDTH_MM = 0.25
GRID_BORDER_MM = 5.0                # plotting grid printed this far inside the paper edge
QUIET_MODULES = 2.0                 # white quiet zone around each marker, in marker modules
DOT_SUPERSAMPLE = 12                # at least this many samples per pixel side ...
DOT_SAMPLES_ACROSS = 160            # ... and at least this many across a dot's minor axis


def make_sheet(*, size_mm=(594.0, 420.0), bottom_left_mm=(-297.0, -210.0),
               dictionary="DICT_5X5_100", marker_mm=20.0, grid=(7, 5),
               margin_mm=15.0) -> Sheet:
    """An ArUco grid spread evenly over the whole sheet (``grid`` = (columns, rows)).

    The outermost markers sit ``margin_mm`` inside the paper edge; ids run 0..n-1 row by row
    from the bottom-left marker (x fastest).
    """
    d = getattr(cv2.aruco, str(dictionary), None)
    if not str(dictionary).startswith("DICT_") or not isinstance(d, int):
        raise VisionCalError(f"unknown ArUco dictionary {dictionary!r}", field="dictionary")
    nx, ny = (int(grid[0]), int(grid[1]))
    if nx < 1 or ny < 1:
        raise VisionCalError(f"expected a grid of at least 1 x 1 markers, got {grid!r}",
                             field="grid")
    n_dict = cv2.aruco.getPredefinedDictionary(d).bytesList.shape[0]
    if nx * ny > n_dict:
        raise VisionCalError(f"{nx * ny} markers but {dictionary} has only {n_dict}",
                             field="grid")
    w, h = float(size_mm[0]), float(size_mm[1])
    s = float(marker_mm)
    x_min, y_min = float(bottom_left_mm[0]), float(bottom_left_mm[1])
    free_x, free_y = w - 2 * margin_mm - s, h - 2 * margin_mm - s
    if s <= 0 or free_x < 0 or free_y < 0:
        raise VisionCalError(f"markers of {s} mm with margin {margin_mm} mm do not fit on a "
                             f"{w} x {h} mm sheet", field="marker_mm")
    xs = x_min + margin_mm + (np.linspace(0, free_x, nx) if nx > 1 else np.array([free_x / 2]))
    ys = y_min + margin_mm + (np.linspace(0, free_y, ny) if ny > 1 else np.array([free_y / 2]))
    need = s * (1 + 2 * QUIET_MODULES / (cv2.aruco.getPredefinedDictionary(d).markerSize + 2))
    if (nx > 1 and xs[1] - xs[0] < need) or (ny > 1 and ys[1] - ys[0] < need):
        raise VisionCalError("markers too close together for their quiet zones", field="grid")
    markers = []
    for r, y0 in enumerate(ys):
        for c, x0 in enumerate(xs):
            corners = np.array([[x0, y0 + s], [x0 + s, y0 + s], [x0 + s, y0], [x0, y0]])
            markers.append(SheetMarker(r * nx + c, corners))
    # say how it is printed (the measurer reads the quiet zone from here, not from us)
    printed = {"module_mm": s / (cv2.aruco.getPredefinedDictionary(d).markerSize + 2),
               "quiet_zone_modules": QUIET_MODULES, "generator": "vision-cal render"}
    return Sheet(str(dictionary), tuple(markers), (w, h), (x_min, y_min),
                 grid=printed_grid((x_min, y_min, x_min + w, y_min + h)).to_json(),
                 printed=printed)


def printed_grid(extent_mm) -> SheetGrid:
    """The plotting grid :func:`sheet_texture` prints on a paper ``extent_mm``: lines at
    whole mm (bold every 10 mm of the sheet frame) from ``GRID_BORDER_MM`` inside the edge."""
    x0, y0, x1, y1 = (float(v) for v in extent_mm)
    lo = (float(np.ceil(x0 + GRID_BORDER_MM)), float(np.ceil(y0 + GRID_BORDER_MM)))
    origin = tuple(float(10.0 * np.ceil(v / 10.0)) for v in lo)  # the first bold lines
    return SheetGrid(1.0, 10, origin, FINE_WIDTH_MM, BOLD_WIDTH_MM,
                     (x0 + GRID_BORDER_MM, y0 + GRID_BORDER_MM, x1 - GRID_BORDER_MM,
                      y1 - GRID_BORDER_MM))


def texture_shape(extent_mm, px_per_mm: float) -> tuple[int, int]:
    """(H, W) of the texture of a paper ``extent_mm`` at ``px_per_mm``; both must be whole."""
    x0, y0, x1, y1 = (float(v) for v in extent_mm)
    wf, hf = (x1 - x0) * px_per_mm, (y1 - y0) * px_per_mm
    W, H = int(round(wf)), int(round(hf))
    if abs(wf - W) > 1e-6 or abs(hf - H) > 1e-6 or W < 1 or H < 1:
        raise VisionCalError(f"sheet {x1 - x0} x {y1 - y0} mm at {px_per_mm} px/mm is not a "
                             "whole number of pixels; choose another px_per_mm",
                             field="px_per_mm")
    return H, W


def sheet_to_texture_pixel(xy_mm, *, extent_mm, px_per_mm: float) -> np.ndarray:
    """Sheet mm (N, 2) to texture pixel coordinates (u = col, v = row; integer at pixel
    centres)."""
    xy = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
    x0, _, _, y1 = (float(v) for v in extent_mm)
    return np.column_stack([(xy[:, 0] - x0) * px_per_mm - 0.5,
                            (y1 - xy[:, 1]) * px_per_mm - 0.5])


# --------------------------------------------------------------------------- coverage helpers

def _overlap(lo_px: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Fraction of each unit pixel interval [lo, lo+1) covered by intervals [a, b) (broadcast)."""
    return np.clip(np.minimum(lo_px + 1.0, b) - np.maximum(lo_px, a), 0.0, 1.0)


def _line_coverage(n_px: int, start_mm: float, sign: float, ppm: float, *, lo_mm: float,
                   hi_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Coverage (fine, bold) of each pixel of a 1-D axis by lines at integer mm.

    Pixel k spans mm coordinate ``start_mm + sign * [k, k+1) / ppm``. Lines only in
    [lo_mm, hi_mm]. Returns two float64 arrays of length n_px in [0, 1].
    """
    k = np.arange(n_px, dtype=float)
    centre_mm = start_mm + sign * (k + 0.5) / ppm
    fine = np.zeros(n_px)
    bold = np.zeros(n_px)
    nearest = np.floor(centre_mm + 0.5)
    for off in (-1.0, 0.0, 1.0):
        line = nearest + off
        ok = (line >= lo_mm - 1e-9) & (line <= hi_mm + 1e-9)
        is_bold = np.mod(np.round(line), 10) == 0
        for width, out, sel in ((FINE_WIDTH_MM, fine, ~is_bold), (BOLD_WIDTH_MM, bold, is_bold)):
            # line interval in pixel units along this axis
            pa = (line - width / 2 - start_mm) * sign * ppm
            pb = (line + width / 2 - start_mm) * sign * ppm
            a, b = np.minimum(pa, pb), np.maximum(pa, pb)
            cov = _overlap(k, a, b)
            out += np.where(ok & sel, cov, 0.0)
    return np.minimum(fine, 1.0), np.minimum(bold, 1.0)


def _rect_coverage(extent_mm, ppm, shape, x_mm: np.ndarray, y_mm: np.ndarray):
    """Pixel box and 1-D coverage of the axis cells [x_mm[k], x_mm[k+1]) x [y_mm[m], y_mm[m+1]).

    Returns (rows slice, cols slice, cy (h, ny), cx (w, nx)): coverage of pixel (r, c) by cell
    (m, k) is cy[r, m] * cx[c, k]. y cells are given bottom-up in mm and returned top-down.
    """
    H, W = shape
    x0, _, _, y1 = extent_mm
    u = (np.asarray(x_mm, float) - x0) * ppm           # pixel-edge units along columns
    v = (y1 - np.asarray(y_mm, float)[::-1]) * ppm     # along rows, top-down
    c0, c1 = max(int(np.floor(u[0])), 0), min(int(np.ceil(u[-1])), W)
    r0, r1 = max(int(np.floor(v[0])), 0), min(int(np.ceil(v[-1])), H)
    if c1 <= c0 or r1 <= r0:
        return None
    cols = np.arange(c0, c1, dtype=float)[:, None]
    rows = np.arange(r0, r1, dtype=float)[:, None]
    cx = _overlap(cols, u[None, :-1], u[None, 1:])
    cy = _overlap(rows, v[None, :-1], v[None, 1:])
    return slice(r0, r1), slice(c0, c1), cy, cx


def _ellipse_coverage(u: float, v: float, a_px: float, b_px: float, theta: float, shape):
    """Area coverage of an ellipse centred at texture pixel coords (u, v) (centre convention).

    Semi-axes a_px, b_px; ``theta`` the angle of the a axis from +u towards +v. Returns
    (rows slice, cols slice, alpha (h, w) float32) or None when outside the texture.
    """
    H, W = shape
    R = max(a_px, b_px) + 1.0
    c0, c1 = max(int(np.floor(u - R)), 0), min(int(np.ceil(u + R)) + 1, W)
    r0, r1 = max(int(np.floor(v - R)), 0), min(int(np.ceil(v + R)) + 1, H)
    if c1 <= c0 or r1 <= r0:
        return None
    ss = max(DOT_SUPERSAMPLE, int(np.ceil(DOT_SAMPLES_ACROSS / (2.0 * min(a_px, b_px)))))
    sub = (np.arange(ss) + 0.5) / ss - 0.5
    du = (np.arange(c0, c1)[:, None] + sub[None, :]).ravel() - u
    dv = (np.arange(r0, r1)[:, None] + sub[None, :]).ravel() - v
    ct, st = np.cos(theta), np.sin(theta)
    DU, DV = np.meshgrid(du, dv)
    p = (DU * ct + DV * st) / a_px
    q = (-DU * st + DV * ct) / b_px
    inside = (p * p + q * q <= 1.0).astype(np.float32)
    alpha = inside.reshape(r1 - r0, ss, c1 - c0, ss).mean(axis=(1, 3))
    return slice(r0, r1), slice(c0, c1), alpha


def paper_field(shape, rng: np.random.Generator) -> np.ndarray:
    """Relative paper brightness (H, W) float32 around 1: soft blotches plus a faint grain."""
    H, W = shape
    lo = rng.standard_normal((max(H // 64, 2) + 1, max(W // 64, 2) + 1)).astype(np.float32)
    lo = cv2.GaussianBlur(lo, (0, 0), 1.0)
    lo = cv2.resize(lo, (W, H), interpolation=cv2.INTER_CUBIC)
    grain = rng.standard_normal((H, W), dtype=np.float32)
    # 1 + 0.006 lo + 0.004 grain, in place (the same float32 operations in the same order)
    lo *= 0.006
    lo += 1.0
    grain *= 0.004
    lo += grain
    return lo


def sheet_texture(sheet: Sheet, *, marks_xy_mm, mark_diameters_mm=1.2, px_per_mm: float = 8.0,
                  rng=None, grid: bool = True, paper_grain: bool = True,
                  print_field=None) -> np.ndarray:
    """The printed sheet with its pen marks: (H, W, 3) uint8 RGB (see the module docstring).

    ``marks_xy_mm`` (N, 2) sheet positions of the ink dots (may be empty); ``mark_diameters_mm``
    a scalar or (N,) nominal diameters. Each dot is an ellipse of random size (+-10 %), aspect
    (1..1.15) and orientation, centred exactly on its mark. ``grid=False`` leaves out the
    plotting-paper lines, ``paper_grain=False`` gives a uniform paper (test helpers).
    ``print_field``: a :class:`vision_cal.world.print_deviation.PrintField`: the markers'
    black squares grown by its toner and the printed layer (grid, markers) displaced by its
    field (the pen's dots are not).
    """
    return sheet_textures(sheet, marks_xy_mm=marks_xy_mm, mark_diameters_mm=mark_diameters_mm,
                          px_per_mm=px_per_mm, rng=rng, grid=grid, paper_grain=paper_grain,
                          bare=False, print_field=print_field)[0]


def sheet_textures(sheet: Sheet, *, marks_xy_mm, mark_diameters_mm=1.2,
                   px_per_mm: float = 8.0, rng=None, grid: bool = True,
                   paper_grain: bool = True, bare: bool = True, print_field=None):
    """``(with the marks, without them)``: :func:`sheet_texture` with and without its pen
    marks from one build (the paper, grid and markers are drawn once; the second is what
    ``sheet_texture`` gives for no marks and the same ``rng``, byte for byte). ``bare``
    False: ``(with the marks, None)``."""
    rng = np.random.default_rng(rng)
    ppm = float(px_per_mm)
    extent = tuple(float(v) for v in sheet.extent_mm)
    shape = texture_shape(extent, ppm)
    H, W = shape
    x0, y0, x1, y1 = extent
    marks = np.asarray(marks_xy_mm, dtype=float).reshape(-1, 2)
    dia = np.broadcast_to(np.asarray(mark_diameters_mm, dtype=float), (len(marks),))

    paper = paper_field(shape, rng) if paper_grain else np.ones(shape, np.float32)

    # 1-D grid coverage along columns (x) and rows (y, top-down)
    if grid:
        fx, bx = _line_coverage(W, x0, +1.0, ppm, lo_mm=np.ceil(x0 + GRID_BORDER_MM),
                                hi_mm=np.floor(x1 - GRID_BORDER_MM))
        fy, by = _line_coverage(H, y1, -1.0, ppm, lo_mm=np.ceil(y0 + GRID_BORDER_MM),
                                hi_mm=np.floor(y1 - GRID_BORDER_MM))
        # restrict lines to the printed area in the other direction too
        gx_in = _overlap(np.arange(W, dtype=float), (x0 + GRID_BORDER_MM - x0) * ppm,
                         (x1 - GRID_BORDER_MM - x0) * ppm)
        gy_in = _overlap(np.arange(H, dtype=float), (y1 - (y1 - GRID_BORDER_MM)) * ppm,
                         (y1 - (y0 + GRID_BORDER_MM)) * ppm)
    # markers: quiet-zone and black-module coverage patches
    marker_patches = []
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, sheet.aruco_dictionary))
    n_cells = int(dictionary.markerSize) + 2        # with the one-cell black border
    for m in sheet.markers:
        c = np.asarray(m.corners_mm, float)
        mx0, my0 = c[:, 0].min(), c[:, 1].min()
        s = c[:, 0].max() - mx0
        bits = cv2.aruco.generateImageMarker(dictionary, int(m.id), n_cells, borderBits=1)
        n = bits.shape[0]
        black = (bits < 128).astype(float)                  # (n, n), row 0 at the top
        mod = s / n
        q = float((sheet.printed or {}).get("quiet_zone_modules", QUIET_MODULES)) * mod
        quiet = _rect_coverage(extent, ppm, shape, np.array([mx0 - q, mx0 + s + q]),
                               np.array([my0 - q, my0 + s + q]))
        toner = 0.0 if print_field is None else float(print_field.toner_mm)
        if toner > 0:
            cells = _grown_cells(extent, ppm, shape, mx0, my0, mod, black, toner)
        else:
            cells = _rect_coverage(extent, ppm, shape, mx0 + mod * np.arange(n + 1),
                                   my0 + mod * np.arange(n + 1))
        marker_patches.append((quiet, cells, black))
    # dots
    dot_patches = _dot_patches(marks, dia, x0=x0, y1=y1, ppm=ppm, shape=shape, rng=rng)

    out = np.empty((H, W, 3), np.uint8)
    remap = (displacement_maps(print_field, extent, ppm, shape)
             if print_field is not None and print_field.moves else None)
    without = np.empty((H, W, 3), np.uint8) if bare else None
    for ch in range(3):
        if grid:
            kf, kb = 1.0 - FINE_RGB[ch] / 255.0, 1.0 - BOLD_RGB[ch] / 255.0
            tx = ((1.0 - fx * kf) * (1.0 - bx * kb)).astype(np.float32)
            ty = ((1.0 - fy * kf) * (1.0 - by * kb)).astype(np.float32)
            # lines outside the printed area are already cut; lines crossing the border of
            # the other axis are cut by gx_in / gy_in
            tx_cut = 1.0 - (1.0 - tx) * gy_in[:, None].astype(np.float32)  # (H, W) via bcast
            ty_cut = 1.0 - (1.0 - ty[:, None]) * gx_in[None, :].astype(np.float32)
            trans = tx_cut * ty_cut
        else:
            trans = np.ones(shape, np.float32)
        km = 1.0 - MARKER_RGB[ch] / 255.0
        for quiet, cells, black in marker_patches:
            if quiet is not None:
                rs, cs, cy, cx = quiet
                qcov = (cy[:, 0][:, None] * cx[:, 0][None, :]).astype(np.float32)
                trans[rs, cs] = trans[rs, cs] * (1.0 - qcov) + qcov
            if cells is not None and len(cells) == 3:   # grown by toner: coverage given
                rs, cs, mcov = cells
                trans[rs, cs] *= 1.0 - km * mcov
            elif cells is not None:
                rs, cs, cy, cx = cells
                mcov = (cy @ black @ cx.T).astype(np.float32)
                trans[rs, cs] *= 1.0 - km * mcov
        if remap is not None:
            trans = np.clip(cv2.remap(trans, *remap, cv2.INTER_CUBIC,
                                      borderMode=cv2.BORDER_REPLICATE), 0.0, 1.0)
        val = trans
        val *= paper
        val *= PAPER_RGB[ch]
        if without is not None:
            without[:, :, ch] = np.rint(np.clip(val, 0.0, 255.0))
        for rs, cs, alpha in dot_patches:
            val[rs, cs] = val[rs, cs] * (1.0 - alpha) + DOT_RGB[ch] * alpha
        np.clip(val, 0.0, 255.0, out=val)
        out[:, :, ch] = np.rint(val)
    return out, without


def _grown_cells(extent_mm, ppm: float, shape, mx0: float, my0: float, mod: float,
                 black: np.ndarray, toner_mm: float, ss: int = 8):
    """(rows, cols, coverage) of a marker's black modules grown ``toner_mm`` on every side
    (their union dilated by a square), by supersampling ``ss`` x ``ss`` per pixel."""
    H, W = shape
    x0, _, _, y1 = extent_mm
    n = black.shape[0]
    s = n * mod
    c0 = max(int(np.floor((mx0 - toner_mm - x0) * ppm)) - 1, 0)
    c1 = min(int(np.ceil((mx0 + s + toner_mm - x0) * ppm)) + 1, W)
    r0 = max(int(np.floor((y1 - (my0 + s + toner_mm)) * ppm)) - 1, 0)
    r1 = min(int(np.ceil((y1 - (my0 - toner_mm)) * ppm)) + 1, H)
    if c1 <= c0 or r1 <= r0:
        return None
    sub = (np.arange(ss) + 0.5) / ss
    xs = x0 + (np.arange(c0, c1)[:, None] + sub[None, :]).ravel() / ppm
    ys = y1 - (np.arange(r0, r1)[:, None] + sub[None, :]).ravel() / ppm
    # a sample is black when a black module lies within toner_mm (Chebyshev) of it
    pad = np.zeros((n + 2, n + 2), bool)
    pad[1:-1, 1:-1] = black > 0.5          # row 0 at the top of the marker
    hit = np.zeros((len(ys), len(xs)), bool)
    for ex in (-toner_mm, 0.0, toner_mm):
        ci = np.clip(np.floor((xs + ex - mx0) / mod).astype(int) + 1, 0, n + 1)
        for ey in (-toner_mm, 0.0, toner_mm):
            ri = np.clip(np.floor((my0 + s - (ys + ey)) / mod).astype(int) + 1, 0, n + 1)
            hit |= pad[ri[:, None], ci[None, :]]
    cov = hit.reshape(r1 - r0, ss, c1 - c0, ss).mean(axis=(1, 3)).astype(np.float32)
    return slice(r0, r1), slice(c0, c1), cov


def displacement_maps(print_field, extent_mm, ppm: float, shape):
    """cv2.remap maps (float32 (H, W) each) of the printer's field: the paper at q shows the
    layout at ``print_field.layout_at(q)`` (the printed layer is resampled bicubically)."""
    H, W = shape
    x0, _, _, y1 = extent_mm
    qx = (x0 + (np.arange(W, dtype=np.float64) + 0.5) / ppm)[None, :]
    qy = (y1 - (np.arange(H, dtype=np.float64) + 0.5) / ppm)[:, None]
    lx, ly = print_field.layout_at(qx, qy)
    mu = ((lx - x0) * ppm - 0.5).astype(np.float32)
    mv = ((y1 - ly) * ppm - 0.5).astype(np.float32)
    return (np.ascontiguousarray(np.broadcast_to(mu, (H, W))),
            np.ascontiguousarray(np.broadcast_to(mv, (H, W))))


def _dot_patches(marks, dia, *, x0: float, y1: float, ppm: float, shape, rng) -> list:
    """The one dot model: each pen mark an ellipse 0.9-1.1 times its diameter, up to 1.15
    in aspect, at a random angle; ``[(rows, cols, coverage)]`` in pixels of a raster whose
    top-left pixel centre is (x0, y1) in sheet mm."""
    patches = []
    for (mx, my), d in zip(marks, dia):
        f = rng.uniform(0.9, 1.1)
        aspect = rng.uniform(1.0, 1.15)
        theta = rng.uniform(0.0, np.pi)
        r_px = 0.5 * d * f * ppm
        u, v = (mx - x0) * ppm - 0.5, (y1 - my) * ppm - 0.5
        cov = _ellipse_coverage(u, v, r_px * np.sqrt(aspect), r_px / np.sqrt(aspect), theta,
                                shape)
        if cov is not None:
            patches.append(cov)
    return patches


def ink_marks(texture_rgb: np.ndarray, *, extent_mm, px_per_mm: float, marks_xy_mm,
              mark_diameters_mm=1.2, rng=None) -> np.ndarray:
    """Pen marks inked onto any raster of the sheet (a copy; same pixel convention and dot
    model as :func:`sheet_texture`): for photographing a sheet printed by another
    generator, rasterised from its own PDF."""
    rng = np.random.default_rng(rng)
    out = np.array(texture_rgb, dtype=np.float32, copy=True)
    ppm = float(px_per_mm)
    x0, _, _, y1 = (float(v) for v in extent_mm)
    marks = np.asarray(marks_xy_mm, dtype=float).reshape(-1, 2)
    dia = np.broadcast_to(np.asarray(mark_diameters_mm, dtype=float), (len(marks),))
    for rs, cs, alpha in _dot_patches(marks, dia, x0=x0, y1=y1, ppm=ppm,
                                      shape=out.shape[:2], rng=rng):
        out[rs, cs] = out[rs, cs] * (1.0 - alpha[..., None]) + \
            np.asarray(DOT_RGB, np.float32) * alpha[..., None]
    np.rint(out, out=out)   # in place: no raster-sized temporaries
    return np.clip(out, 0, 255, out=out).astype(np.uint8)
