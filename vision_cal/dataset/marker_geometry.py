"""What a sheet description says about its printed markers, and where it comes from.

It belongs to the format (the ``sheet`` block), not to the estimator: the measurer, the
planners and the synthetic world all read it here.

A sheet printed by any generator with the same ``sheet`` block must measure the same
(docs/format.md), so nothing here looks at how this project prints:

- modules per side: the OpenCV dictionary's ``markerSize`` plus the black border (one
  module on each side: OpenCV's detector requires exactly that, whoever printed it);
- the module: the marker side over the modules per side;
- the white quiet zone around each marker: ``sheet.printed.quiet_zone_modules`` (or
  ``quiet_zone_mm`` over the module) when the sheet description says how it was printed,
  else :data:`DEFAULT_QUIET_MODULES`.

``DEFAULT_QUIET_MODULES = 1``: ArUco detection needs a white margin around the black
border and one module is the least a detectable print has (OpenCV's own marker tutorials
print that much); assuming more would take printed grid for bare paper next to markers
printed by someone else. This project's printers (``vision-cal sheet``, the renderer) say
what they print in ``sheet.printed``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

DEFAULT_QUIET_MODULES = 1.0
BORDER_MODULES = 1


@lru_cache(maxsize=64)
def bits_per_side(dictionary: str) -> int:
    """The dictionary's data bits per marker side (``markerSize``), from OpenCV."""
    # OpenCV takes 0.2 s to import: loaded here, when used
    import cv2

    return int(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary)).markerSize)


@dataclass(frozen=True)
class MarkerGeometry:
    """``modules_per_side`` (bits + 2 border modules); ``quiet_modules`` white modules
    around each marker and ``quiet_source`` where that came from (``sheet.printed`` or
    ``default``)."""

    modules_per_side: int
    quiet_modules: float
    quiet_source: str

    def module_mm(self, side_mm) -> np.ndarray:
        return np.asarray(side_mm, float) / self.modules_per_side

    def quiet_mm(self, side_mm) -> np.ndarray:
        return self.quiet_modules * self.module_mm(side_mm)


def marker_geometry(sheet) -> MarkerGeometry:
    """The printed marker geometry of ``sheet`` (a ``Sheet``), see the module docstring."""
    n = bits_per_side(sheet.aruco_dictionary) + 2 * BORDER_MODULES
    printed = getattr(sheet, "printed", None) or {}
    if printed.get("quiet_zone_modules") is not None:
        return MarkerGeometry(n, float(printed["quiet_zone_modules"]), "sheet.printed")
    if printed.get("quiet_zone_mm") is not None and sheet.markers:
        side = float(np.median([marker_side_mm(m.corners_mm) for m in sheet.markers]))
        module = float(printed.get("module_mm") or side / n)
        return MarkerGeometry(n, float(printed["quiet_zone_mm"]) / module, "sheet.printed")
    return MarkerGeometry(n, DEFAULT_QUIET_MODULES, "default")


def marker_side_mm(corners_mm) -> float:
    """Mean side length of one marker's corner quadrilateral (4, 2)."""
    c = np.asarray(corners_mm, float).reshape(4, 2)
    return float(np.mean(np.hypot(*(np.roll(c, -1, axis=0) - c).T)))


def marker_boxes_mm(sheet, pad_mm=0.0) -> np.ndarray:
    """(M, 4) [x0, y0, x1, y1]: each printed marker's bounding box in the sheet frame,
    grown by ``pad_mm`` (a number, or (M,) one per marker). The one owner of the boxes
    kept clear of pen marks (measurer masks, planners, the world's labels)."""
    c = np.array([np.asarray(m.corners_mm, float).reshape(4, 2) for m in sheet.markers],
                 float).reshape(-1, 4, 2)
    pad = np.broadcast_to(np.asarray(pad_mm, float), (len(c),))[:, None]
    return np.hstack([c.min(axis=1) - pad, c.max(axis=1) + pad]).reshape(-1, 4)


def quiet_boxes_mm(sheet) -> np.ndarray:
    """(M, 4) [x0, y0, x1, y1]: each marker's bounding box grown by its quiet zone."""
    g = marker_geometry(sheet)
    q = [float(g.quiet_mm(marker_side_mm(m.corners_mm))) for m in sheet.markers]
    return marker_boxes_mm(sheet, q)
