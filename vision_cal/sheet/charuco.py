"""A ChArUco board (``vision-cal sheet --charuco COLSxROWS``): OpenCV's board of squares with
a marker in each white square, printed at true scale, and its sheet.json.

OpenCV's ``cv2.aruco.CharucoBoard((cols, rows), square, marker, dictionary)`` says which
squares hold a marker (the white ones; ``legacy`` moves them by one square on boards with
an even number of rows, as OpenCV before 4.6 did) and numbers the chessboard's inner
corners row by row from the top left. This module takes that pattern from OpenCV and
writes every position in float64 from the board's numbers (OpenCV keeps them in float32:
up to 4e-6 mm off), in the sheet frame: x right, y up, origin at the board's centre, so a
board point (x, y) of OpenCV's frame (origin at the top-left corner, y down) is
``(x - W/2, H/2 - y)``.

sheet.json is the usual sheet block (the markers' corners, TL TR BR BL of the upright
marker) plus ``charuco`` (docs/format.md, "A ChArUco board"): ``squares`` [cols, rows],
``square_mm``, ``marker_mm``, ``legacy_pattern``, ``ids`` (the markers' ids in OpenCV's
order) and ``corners_mm`` (the chessboard's inner corners in the sheet frame, id = index),
which is what lets the hand-eye read the chessboard's saddle points rather than only the
markers' corners (:mod:`vision_cal.camera.board`).
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass

import numpy as np

from vision_cal import __version__
from vision_cal.errors import VisionCalError
from vision_cal.sheet.layout import (EDGE_MM, GENERATOR, ISO_SIZES_MM, MARKER_RGB, TEXT_MM,
                                     MarkerCells, Rect, SheetLayout, Text, aruco_dictionary,
                                     rounded,
                                     marker_bits, page_size_mm, with_primitives)

#: the most squares a board may have along a side (OpenCV's boards go to a few dozen)
MAX_SQUARES = 100


@dataclass(frozen=True)
class CharucoSpec:
    """A ChArUco board's numbers: ``squares`` (cols, rows), sizes in mm, the dictionary's
    name, OpenCV's legacy pattern flag and the markers' ids (None: 0, 1, ...)."""

    squares: tuple[int, int]
    square_mm: float
    marker_mm: float
    dictionary: str
    legacy_pattern: bool = False
    ids: tuple[int, ...] | None = None

    @property
    def size_mm(self) -> tuple[float, float]:
        return (self.squares[0] * self.square_mm, self.squares[1] * self.square_mm)

    def opencv_board(self):
        """``cv2.aruco.CharucoBoard`` of this spec (OpenCV's own pattern and ids)."""
        # OpenCV takes 0.2 s to import: loaded here, when used
        import cv2

        d = aruco_dictionary(self.dictionary)
        if self.ids is None:
            b = cv2.aruco.CharucoBoard(tuple(self.squares), float(self.square_mm),
                                       float(self.marker_mm), d)
        else:
            b = cv2.aruco.CharucoBoard(tuple(self.squares), float(self.square_mm),
                                       float(self.marker_mm), d, np.asarray(self.ids, np.int32))
        b.setLegacyPattern(bool(self.legacy_pattern))
        return b

    def marker_squares(self) -> list[tuple[int, int, int]]:
        """(id, col, row) of each marker in OpenCV's order (row 0 at the board's top)."""
        b = self.opencv_board()
        out = []
        for mid, pts in zip(np.asarray(b.getIds()).ravel(), b.getObjPoints()):
            c = np.asarray(pts, float).reshape(4, 3).mean(axis=0)
            out.append((int(mid), int(c[0] // self.square_mm), int(c[1] // self.square_mm)))
        return out

    def to_sheet(self, xy_cv: np.ndarray) -> np.ndarray:
        """OpenCV board points (N, 2) (origin top-left, y down) -> sheet frame (y up,
        origin at the centre)."""
        W, H = self.size_mm
        p = np.asarray(xy_cv, float).reshape(-1, 2)
        return np.c_[p[:, 0] - W / 2.0, H / 2.0 - p[:, 1]]

    def chessboard_corners_mm(self) -> np.ndarray:
        """(N, 2) the inner corners in the sheet frame, OpenCV's id order (row by row from
        the top left)."""
        c, r = self.squares
        s = self.square_mm
        xy = np.array([[i * s, j * s] for j in range(1, r) for i in range(1, c)], float)
        return self.to_sheet(xy)

    def markers_mm(self) -> list[tuple[int, np.ndarray]]:
        """(id, corners (4, 2) TL TR BR BL of the upright marker) in the sheet frame."""
        s, m = self.square_mm, self.marker_mm
        off = (s - m) / 2.0
        out = []
        for mid, col, row in self.marker_squares():
            x0, y0 = col * s + off, row * s + off       # OpenCV frame, top-left corner
            cv = np.array([[x0, y0], [x0 + m, y0], [x0 + m, y0 + m], [x0, y0 + m]])
            out.append((mid, self.to_sheet(cv)))
        return out

    def to_json(self) -> dict:
        return {"squares": list(self.squares), "square_mm": rounded(self.square_mm),
                "marker_mm": rounded(self.marker_mm),
                "legacy_pattern": bool(self.legacy_pattern),
                "ids": [m for m, _, _ in self.marker_squares()],
                "corners_mm": rounded(self.chessboard_corners_mm().tolist())}


def parse_squares(text: str) -> tuple[int, int]:
    """``"5x7"`` -> (5, 7): columns by rows, each 2..MAX_SQUARES."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", str(text))
    if not m:
        raise VisionCalError(f"expected COLSxROWS like 5x7, got {text!r}", field="--charuco")
    c, r = int(m.group(1)), int(m.group(2))
    if not (2 <= c <= MAX_SQUARES and 2 <= r <= MAX_SQUARES):
        raise VisionCalError(f"expected 2 to {MAX_SQUARES} squares a side, got {c}x{r}",
                             field="--charuco")
    return c, r


def charuco_spec(squares: tuple[int, int], square_mm, marker_mm, dictionary: str,
                 legacy_pattern: bool = False) -> CharucoSpec:
    """The board's numbers checked (the option named where one is wrong)."""
    for name, v in (("--square-mm", square_mm), ("--marker-mm", marker_mm)):
        if v is None:
            raise VisionCalError("a ChArUco board needs it", field=name)
        if not (math.isfinite(float(v)) and 0 < float(v) <= 1000.0):
            raise VisionCalError(f"expected a size in mm (0 to 1000), got {v!r}", field=name)
    if not float(marker_mm) < float(square_mm):
        raise VisionCalError(f"the marker ({marker_mm:g} mm) must be smaller than its square "
                             f"({square_mm:g} mm)", field="--marker-mm")
    d = aruco_dictionary(dictionary)
    spec = CharucoSpec(tuple(squares), float(square_mm), float(marker_mm), str(dictionary),
                       bool(legacy_pattern))
    n = (squares[0] * squares[1]) // 2
    if n > int(d.bytesList.shape[0]):
        raise VisionCalError(f"the board needs {n} markers but {dictionary} has only "
                             f"{int(d.bytesList.shape[0])}", field="--dictionary")
    return spec


@dataclass(frozen=True)
class CharucoLayout(SheetLayout):
    """A :class:`SheetLayout` of a ChArUco board: no ruled grid, no scale bars, the
    ``charuco`` block in sheet.json (its ``sheet_id`` covers the squares too)."""

    spec: CharucoSpec | None = None

    @property
    def sheet_id(self) -> str:
        key = json.dumps([super().sheet_id, self.spec.to_json()])
        return hashlib.sha256(key.encode()).hexdigest()[:8]

    def to_sheet_json(self) -> dict:
        d = super().to_sheet_json()
        d.pop("grid", None)
        p = d["printed"]
        for k in ("scale_bars_mm", "scale_bar_length_mm", "drawable_mm"):
            p.pop(k, None)
        p["kind"] = "charuco"
        p["sheet_id"] = self.sheet_id
        d["charuco"] = self.spec.to_json()
        return d


def _page_for(board_mm: tuple[float, float], size, landscape, custom_mm):
    """The page: the one asked for, else the smallest ISO page holding the board with its
    margins (and the title line)."""
    need = (board_mm[0] + 2 * EDGE_MM, board_mm[1] + 2 * EDGE_MM + 2 * TEXT_MM + 4.0)
    if size is None and custom_mm is None:
        for name in ("A4", "A3", "A2", "A1", "A0"):
            for land in (False, True):
                _, _, (w, h) = page_size_mm(name, landscape=land)
                if w >= need[0] and h >= need[1]:
                    size, landscape = name, land
                    break
            if size is not None:
                break
        if size is None:
            custom_mm = need
    page, orientation, (W, H) = page_size_mm(size, landscape=landscape, custom_mm=custom_mm)
    if W < need[0] or H < need[1]:
        raise VisionCalError(f"a {W:g} x {H:g} mm page cannot hold the {board_mm[0]:g} x "
                             f"{board_mm[1]:g} mm board and its margins",
                             field="--custom" if custom_mm is not None else "--size")
    return page, orientation, (W, H)


def make_charuco_layout(spec: CharucoSpec, *, size: str | None = None,
                        landscape: bool | None = None, custom_mm=None,
                        version: str | None = None) -> CharucoLayout:
    """The board centred on a page (the sheet frame's origin at its centre), its black
    squares and markers, and a title line under it."""
    version = __version__ if version is None else version
    W_b, H_b = spec.size_mm
    page, orientation, (W, H) = _page_for((W_b, H_b), size, landscape, custom_mm)
    d = aruco_dictionary(spec.dictionary)
    module = spec.marker_mm / (int(d.markerSize) + 2)
    quiet = (spec.square_mm - spec.marker_mm) / 2.0 / module
    s = spec.square_mm
    taken = {(col, row) for _, col, row in spec.marker_squares()}
    prims: list = []
    for row in range(spec.squares[1]):
        for col in range(spec.squares[0]):
            if (col, row) not in taken:
                (x0, y1), (x1, y0) = spec.to_sheet([[col * s, row * s],
                                                    [(col + 1) * s, (row + 1) * s]])
                prims.append(Rect(float(x0), float(y0), float(x1), float(y1), MARKER_RGB))
    markers = []
    for mid, c in spec.markers_mm():
        bl = c[3]
        markers.append(MarkerCells(mid, float(bl[0]), float(bl[1]), module,
                                   marker_bits(spec.dictionary, mid)))
    markers.sort(key=lambda m: m.id)
    prims.extend(markers)
    ext = (-W_b / 2.0, -H_b / 2.0, W_b / 2.0, H_b / 2.0)
    layout = CharucoLayout(page, orientation, (W, H), (-W / 2.0, -H / 2.0), spec.dictionary,
                           module, float(quiet), tuple(markers), ext, ext, {}, (),
                           str(version), None, spec)
    line = (f"PRINT AT 100 % (actual size). vision-cal sheet --charuco {spec.squares[0]}x"
            f"{spec.squares[1]} {layout.sheet_id} | squares {s:g} mm, markers "
            f"{spec.marker_mm:g} mm, {spec.dictionary}"
            + (", legacy pattern" if spec.legacy_pattern else "")
            + f" | {page} {orientation} | {GENERATOR} {version}")
    width = min(W - 2 * EDGE_MM, max(W_b, 120.0))
    prims.append(Text(-width / 2.0, -H_b / 2.0 - TEXT_MM - 2.0, line,
                      min(TEXT_MM, 0.9 * width / max(len(line) * 0.55, 1.0))))
    return with_primitives(layout, tuple(prims))


__all__ = ["CharucoLayout", "CharucoSpec", "ISO_SIZES_MM", "charuco_spec",
           "make_charuco_layout", "parse_squares"]
