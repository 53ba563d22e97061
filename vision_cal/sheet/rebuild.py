"""The printed sheet again from its sheet.json: the same layout, so the same raster.

``vision-cal sheet`` records in sheet.json everything its layout depends on (page, dictionary,
module, quiet zone, the marker ring) except the ``--pitch-mm`` it was given; the ring's
spacing gives it back (any pitch between the largest spacing and the next ring size builds the
same ring). :func:`layout_from_sheet_json` rebuilds the layout and checks that it is the
printed one (the same markers and ``sheet_id``, the content hash of the printed geometry), so a rehearsal
(``vision-cal simulate``) can photograph exactly the sheet the user printed without a
``sheet.png`` having been written. A sheet from another generator cannot be rebuilt: the
error says to give its raster.
"""

from __future__ import annotations

import numpy as np

from vision_cal.errors import VisionCalError
from vision_cal.sheet.layout import GENERATOR, ISO_SIZES_MM, SheetLayout, make_layout


def _ring_pitch_mm(markers: list) -> float | None:
    """A pitch that rebuilds the ring of ``markers`` (sheet.json entries), None for one marker."""
    xs = sorted({round(min(c[0] for c in m["corners_mm"]), 6) for m in markers})
    ys = sorted({round(min(c[1] for c in m["corners_mm"]), 6) for m in markers})
    gaps = [float(np.diff(v).max()) for v in (xs, ys) if len(v) > 1]
    return max(gaps) * (1.0 + 1e-7) if gaps else None


def layout_from_sheet_json(doc: dict, *, file: str | None = None) -> SheetLayout:
    """The :class:`SheetLayout` that ``vision-cal sheet`` printed for this sheet block.

    Raises ``VisionCalError`` (naming ``printed`` or ``sheet_id``) when the block was not
    written by ``vision-cal sheet`` or the rebuilt sheet is not the same print.
    """
    printed = doc.get("printed") if isinstance(doc, dict) else None
    if not isinstance(printed, dict) or printed.get("generator") != GENERATOR:
        raise VisionCalError(f"not written by `{GENERATOR}`: its raster cannot be rebuilt; "
                             "give the printed sheet's image (sheet.png beside sheet.json)",
                             file=file, field="printed.generator")
    try:
        page = printed["page"]
        W, H = (float(v) for v in page["size_mm"])
        landscape = page["orientation"] == "landscape"
        name = page["name"]
        quiet = float(printed["quiet_zone_modules"])
        markers = doc["markers"]
        c = np.asarray(markers[0]["corners_mm"], dtype=float)
        side_mm = round(float(c[:, 0].max() - c[:, 0].min()), 6)   # the file's precision
        kw = dict(dictionary=doc["aruco_dictionary"], marker_mm=side_mm,
                  pitch_mm=_ring_pitch_mm(markers), quiet_modules=quiet,
                  measured_bar_mm=printed.get("measured_bar_mm"), version=printed.get("version"))
        if name in ISO_SIZES_MM:
            layout = make_layout(size=name, landscape=landscape, **kw)
        else:
            layout = make_layout(size=None, custom_mm=(W, H), **kw)
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise VisionCalError(f"incomplete sheet description ({e!r}): give the printed sheet's "
                             "image (sheet.png beside sheet.json)", file=file,
                             field="printed") from e
    again = layout.to_sheet_json()["markers"]
    same = len(again) == len(markers) and all(
        a["id"] == m.get("id") and np.allclose(a["corners_mm"], m.get("corners_mm"), atol=1e-5)
        for a, m in zip(again, markers))
    if not same or layout.sheet_id != printed.get("sheet_id"):
        raise VisionCalError(f"the rebuilt sheet is {layout.sheet_id}, not the printed "
                             f"{printed.get('sheet_id')}: give the printed sheet's image "
                             "(sheet.png beside sheet.json)", file=file, field="printed.sheet_id")
    return layout
