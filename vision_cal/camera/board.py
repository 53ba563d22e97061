"""A calibration board for the hand-eye: a sheet.json (docs/format.md) read, and its points
found in a photo.

Two kinds of board:

- a ChArUco board (sheet.json with a ``charuco`` block, written by ``vision-cal sheet
  --charuco`` or by hand): the chessboard's inner corners, saddle points that locate better
  than markers' corners (OpenCV 5's ``cv2.aruco.CharucoDetector``: markers found, then
  the saddles between them interpolated and refined to sub-pixel; markers the first pass
  missed looked for again where the board says they are, ``tryRefineMarkers``). The
  block's ``corners_mm`` and the markers must be OpenCV's board of those numbers (checked:
  a hand-written block that is not is refused naming the field);
- any other sheet.json (a plain ArUco grid, ``vision-cal sheet --field``, or this
  project's ring sheet): its markers' four corners, found by the measurement's own
  detector (:func:`vision_cal.measure.aruco.find_sheet_markers`) and placed where the
  markers' fitted sides meet (``edge_points``, ``corners_from_edges``).

Points are in the board's frame: the sheet frame (x right, y up, origin where the sheet
says), z = 0 on the board, out of the printed side.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vision_cal.dataset.fields import FieldReader
from vision_cal.dataset.io import read_json
from vision_cal.dataset.session import Sheet, read_sheet_block
from vision_cal.dataset.marker_geometry import marker_geometry
from vision_cal.measure.aruco import (corners_from_edges, detect_raw, edge_points,
                                      find_sheet_markers)
from vision_cal.sheet.charuco import CharucoSpec, MAX_SQUARES

#: the points' kinds
SADDLE, MARKER = "saddle", "marker corner"
#: a hand-written board's point may be off OpenCV's by this much (mm) and still be its board
MATCH_MM = 1e-3


@dataclass(frozen=True)
class Board:
    """A board: its sheet block, the ChArUco numbers when it has saddles (else None) and
    the file it came from."""

    sheet: Sheet
    charuco: CharucoSpec | None
    path: str

    @property
    def kind(self) -> str:
        return SADDLE if self.charuco is not None else MARKER

    def describe(self) -> str:
        if self.charuco is not None:
            c = self.charuco
            return (f"ChArUco {c.squares[0]}x{c.squares[1]} squares of {c.square_mm:g} mm, "
                    f"markers {c.marker_mm:g} mm, {c.dictionary}"
                    + (" (legacy pattern)" if c.legacy_pattern else ""))
        return (f"{len(self.sheet.markers)} {self.sheet.aruco_dictionary} markers "
                "(their corners)")


def _read_charuco(r: FieldReader, block, sheet: Sheet) -> CharucoSpec:
    """The ``charuco`` block, checked against OpenCV's board of its numbers."""
    w = "charuco"
    if not isinstance(block, dict):
        r.fail(w, f"expected an object, got {type(block).__name__}")
    sq = r.list_(r.get(block, "squares", w), f"{w}.squares")
    if len(sq) != 2:
        r.fail(f"{w}.squares", "expected [columns, rows]")
    cols, rows = (r.integer(v, f"{w}.squares[{i}]", lo=2, hi=MAX_SQUARES)
                  for i, v in enumerate(sq))
    square = r.number(r.get(block, "square_mm", w), f"{w}.square_mm", lo=0.0, hi=1000.0)
    marker = r.number(r.get(block, "marker_mm", w), f"{w}.marker_mm", lo=0.0, hi=1000.0)
    if not 0 < marker < square:
        r.fail(f"{w}.marker_mm", f"expected a marker smaller than its square ({square:g} "
                                 f"mm), got {marker:g}")
    legacy = r.boolean(block.get("legacy_pattern", False), f"{w}.legacy_pattern")
    ids = block.get("ids")
    if ids is not None:
        ids = tuple(r.integer(v, f"{w}.ids[{i}]", lo=0)
                    for i, v in enumerate(r.list_(ids, f"{w}.ids")))
        if len(ids) != (cols * rows) // 2:
            r.fail(f"{w}.ids", f"expected {(cols * rows) // 2} ids (one a white square), got "
                               f"{len(ids)}")
    spec = CharucoSpec((cols, rows), square, marker, sheet.aruco_dictionary, legacy, ids)
    declared = {m.id: np.asarray(m.corners_mm, float) for m in sheet.markers}
    for mid, c in spec.markers_mm():
        if mid not in declared:
            r.fail("markers", f"marker {mid} of the ChArUco board is not listed")
        if np.abs(declared[mid] - c).max() > MATCH_MM:
            r.fail("markers", f"marker {mid} is not where OpenCV's CharucoBoard(({cols}, "
                              f"{rows}), {square:g}, {marker:g}) puts it (the sheet frame's "
                              "origin at the board's centre, y up): "
                              f"{np.round(declared[mid], 3).tolist()} against "
                              f"{np.round(c, 3).tolist()}")
    if block.get("corners_mm") is not None:
        cm = r.list_(block["corners_mm"], f"{w}.corners_mm")
        got = np.array([r.point(p, f"{w}.corners_mm[{i}]") for i, p in enumerate(cm)])
        want = spec.chessboard_corners_mm()
        if got.shape != want.shape or np.abs(got - want).max() > MATCH_MM:
            r.fail(f"{w}.corners_mm", "not the chessboard corners of those squares (OpenCV's "
                                      "order, row by row from the top left)")
    return spec


def load_board(path) -> Board:
    """A board from a sheet.json (its ``charuco`` block when it has one)."""
    path = Path(path)
    raw = read_json(path, what="board (sheet.json)")
    r = FieldReader(str(path))
    sheet = read_sheet_block(r, raw, "")
    charuco = _read_charuco(r, raw["charuco"], sheet) if raw.get("charuco") is not None \
        else None
    return Board(sheet, charuco, str(path))


@dataclass(frozen=True)
class BoardPoints:
    """A board's points seen in one photo: ``ids`` (N,) (a saddle's OpenCV id, a marker
    corner's ``4 * marker id + corner``), ``board_mm`` (N, 3), ``px`` (N, 2); the board's
    markers found, the dictionary's markers that are not on the board (``foreign``), and
    ``reason`` when the photo cannot be used (else None)."""

    ids: np.ndarray
    board_mm: np.ndarray
    px: np.ndarray
    n_markers: int
    foreign: tuple[int, ...]
    reason: str | None


@dataclass(frozen=True)
class _Detector:
    board: object
    detector: object


_DETECTORS: dict = {}


def _charuco_detector(spec: CharucoSpec):
    """OpenCV's ChArUco detector of ``spec`` (kept: built once a process)."""
    # OpenCV takes 0.2 s to import: loaded here, when a photo is read
    import cv2

    key = spec
    if key not in _DETECTORS:
        board = spec.opencv_board()
        cp = cv2.aruco.CharucoParameters()
        cp.tryRefineMarkers = True
        _DETECTORS[key] = _Detector(board, cv2.aruco.CharucoDetector(
            board, cp, cv2.aruco.DetectorParameters()))
    return _DETECTORS[key]


def find_board(image: np.ndarray, board: Board, *, min_points: int = 6) -> BoardPoints:
    """The board's points in a photo (BGR or grey, uint8: saddles for a ChArUco board,
    else markers' corners); ``reason`` set when fewer than ``min_points`` are found or
    most markers seen belong to another board."""
    # OpenCV takes 0.2 s to import: loaded here, when a photo is read
    import cv2

    gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    own = {m.id for m in board.sheet.markers}
    if board.charuco is None:
        det = find_sheet_markers(gray, board.sheet)
        n = len(det.ids)
        ids = (4 * np.repeat(det.ids, 4) + np.tile(np.arange(4), n)).astype(int)
        mm = np.c_[det.corners_mm.reshape(-1, 2), np.zeros(4 * n)]
        # the measurement's own corners: the four sides' sub-pixel edges, lines met
        edges = edge_points(gray, det.corners_px, geometry=marker_geometry(board.sheet))
        px = corners_from_edges(edges, det.corners_px).reshape(-1, 2)
        reason = det.reason
        foreign = tuple(sorted({int(i) for i in detect_raw(gray, board.sheet.aruco_dictionary)[0]
                                if int(i) not in own})) if det.n_foreign else ()
    else:
        d = _charuco_detector(board.charuco)
        cc, ci, _, mi = d.detector.detectBoard(gray)
        seen = [] if mi is None else [int(i) for i in np.asarray(mi).ravel()]
        foreign = tuple(sorted({i for i in seen if i not in own}))
        n = len(seen) - sum(1 for i in seen if i not in own)
        if ci is None or len(ci) == 0:
            ids, px = np.zeros(0, int), np.zeros((0, 2))
        else:
            ids = np.asarray(ci, int).ravel()
            px = np.asarray(cc, float).reshape(-1, 2)
        corners = board.charuco.chessboard_corners_mm()
        mm = np.c_[corners[ids], np.zeros(len(ids))] if len(ids) else np.zeros((0, 3))
        reason = None
    if len(foreign) >= 2 and len(foreign) > n:
        reason = (f"another board: {len(foreign)} {board.sheet.aruco_dictionary} markers that "
                  f"are not on {Path(board.path).name} (ids {', '.join(map(str, foreign[:8]))}"
                  f"{', ...' if len(foreign) > 8 else ''}), {n} that are")
    elif reason is None and len(ids) < min_points:
        reason = (f"too little of the board: {len(ids)} {board.kind}s found, at least "
                  f"{min_points} needed")
    return BoardPoints(ids, mm, px, n, foreign, reason)


__all__ = ["Board", "BoardPoints", "MARKER", "SADDLE", "find_board", "load_board"]
