"""Each identified mark combined over its photos (:func:`mark_measurements`), then the
sheet's height from the marks' dots (stage 4, :func:`sheet_height_stage`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from vision_cal.config import AssociationConfig, EstimatorConfig
from vision_cal.dataset.session import Session
from vision_cal.errors import VisionCalError
from vision_cal.identify import associate as assoc
from vision_cal.identify.match import AssociatedDots
from vision_cal.measure.height import sheet_heights
from vision_cal.measure.mapping import LensEstimate
from vision_cal.measure.types import ImageResult, MarkMeasurement, dot_field


def _without_flagged(g, images: list[ImageResult]):
    """The group without the dots that could not be separated from the print under them
    (all of it when none or every dot is flagged)."""
    keep = [i for i, (k, j) in enumerate(zip(g.images, g.dot_index))
            if not dot_field(images[k], "dots_unreliable", j)]
    if not keep or len(keep) == len(g.images):
        return g
    return assoc.DotGroup(g.xy_mm[keep], g.cov_mm2[keep], tuple(g.images[i] for i in keep),
                          tuple(g.dot_index[i] for i in keep))


def mark_measurements(dots: AssociatedDots, images: list[ImageResult], files: list[str],
                      ac: AssociationConfig) -> dict[str, MarkMeasurement]:
    """Each associated mark combined over its photos (id -> :class:`MarkMeasurement`):
    "unreliable" when every photo's dot of it was, else measured without the flagged ones;
    the reference (grid, markers or mixed) and the local-minus-global difference."""
    marks = {}
    for mid, gi in dots.assoc.mark_to_group.items():
        g = dots.measured_group(gi)
        if not len(g.images):   # its refined views were all in photos left out
            continue
        why = [dot_field(images[k], "dots_unreliable", j) for k, j in zip(g.images, g.dot_index)]
        status, reason = "ok", ""
        if all(why):
            status, reason = "unreliable", why[0]
        else:   # measured without the photos whose dot could not be separated
            g = _without_flagged(g, images)
        under = next((u for u in (dot_field(images[k], "dots_printed_under", j)
                                  for k, j in zip(g.images, g.dot_index)) if u), "")
        xy, cov, spread = assoc.combine(g, common_fraction=ac.common_fraction)
        refs = [images[k].dots_reference[j] for k, j in zip(g.images, g.dot_index)]
        ref = refs[0] if len(set(refs)) == 1 else "mixed"
        offs = np.array([images[k].dots_grid_offset_mm[j] for k, j in zip(g.images, g.dot_index)])
        offs = offs[np.all(np.isfinite(offs), axis=1)]
        lmg = lmg_sd = None
        if len(offs):  # local minus global = minus the grid's offset
            lmg = -offs.mean(axis=0)
            lmg_sd = (offs.std(axis=0, ddof=1) / np.sqrt(len(offs)) if len(offs) > 1
                      else np.full(2, np.nan))
        marks[mid] = MarkMeasurement(xy, cov, len(g.images), spread,
                                     dots.assoc.how.get(mid, "model"),
                                     tuple(files[k] for k in g.images), ref,
                                     lmg, lmg_sd, status, reason, under)
    return marks


def sheet_height_stage(session: Session, images: list[ImageResult], marks: dict,
                       dots: AssociatedDots, lens: LensEstimate | None,
                       config: EstimatorConfig):
    """Stage 4: the sheet's height (parallax against the grid or between camera places).
    A paper that is not flat moves the marks seen through the marker mapping alone to the
    position parallax found; a flat one puts the grid-referenced marks back on the marker
    mapping (the line phase adds its own few micrometres; the grid's difference stays
    reported). Dots that could not be separated from the print under them, and marks none
    of whose dots could, are no evidence of heights either (their grid offsets carry the
    ink beside them). ``marks`` is updated; returns (heights, height map or None, note or
    None)."""
    groups_of = {}
    for mid, gi in dots.assoc.mark_to_group.items():
        if mid in marks and marks[mid].status == "ok":
            g = _without_flagged(dots.measured_group(gi), images)
            groups_of[mid] = list(zip(g.images, g.dot_index))
    heights, hmap, hnote = {}, None, None
    try:
        heights, hmap, hnote = sheet_heights(images, marks, groups_of, session.sheet.extent_mm,
                                             K_fallback=None if lens is None else lens.K,
                                             config=config)
    except (VisionCalError, np.linalg.LinAlgError) as e:
        hnote = f"no height map: {e}"
    if hmap is not None and hmap.claimed:
        for mid, h in heights.items():
            mm = marks[mid]
            if mm.reference == "markers" and h.xy_mm is not None:
                marks[mid] = replace(mm, xy_mm=h.xy_mm, cov_mm2=h.cov_xy_mm2,
                                     reference="parallax")
    elif heights:
        for mid, gi in dots.assoc.mark_to_group.items():
            mm = marks.get(mid)
            if mm is None or mm.reference == "markers":
                continue
            g = _without_flagged(dots.measured_group(gi), images)
            gg = assoc.DotGroup(
                np.array([images[k].dots_global_xy_mm[j] for k, j in zip(g.images, g.dot_index)]),
                np.array([images[k].dots_global_cov_mm2[j]
                          for k, j in zip(g.images, g.dot_index)]), g.images, g.dot_index)
            xy, cov, spread = assoc.combine(gg,
                                            common_fraction=config.association.common_fraction)
            marks[mid] = replace(mm, xy_mm=xy, cov_mm2=cov, spread_mm=spread,
                                 reference="markers (sheet flat)")
    return heights, hmap, hnote
