"""The print (#28): the sheet as printed (a survey, or estimated from photos taken from
several places, :func:`as_printed_stage`) and measurement.json's ``print`` block, the
limit the print leaves on the marks (:func:`print_stage`)."""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from vision_cal.config import EstimatorConfig
from vision_cal.dataset.session import Session
from vision_cal.measure.asprinted import AsPrinted, estimate_as_printed, field_basis
from vision_cal.measure.finish import lens_of
from vision_cal.measure.mapping import LensEstimate
from vision_cal.measure.types import ImageDetections, ImageResult

log = logging.getLogger(__name__)


def as_printed_stage(session: Session, dets: list[ImageDetections], lens: LensEstimate | None,
                     config: EstimatorConfig, *, survey: AsPrinted | None = None):
    """The sheet as printed (:mod:`vision_cal.measure.asprinted`): the survey's layout when
    one is given, else estimated from these photos when they were taken from at least
    ``config.as_printed.min_places`` places and off its layout beyond
    ``config.as_printed.min_deviation_ratio`` times what they leave unresolved. Returns
    (as_printed or None, lens, detections
    with their markers' corners as printed); an estimated lens is then the one solved with
    the layout (the stage-2 lens absorbed part of the print), when stage 2 kept one; and
    the layout found but not used (None when used or not found)."""
    ap = survey
    if ap is None:
        ok = [d for d in dets if d.status == "ok"]
        sizes = sorted({d.size_px for d in ok}, key=lambda s: -sum(x.size_px == s for x in ok))
        if not sizes:
            return None, lens, dets, None
        size = sizes[0]
        K, dist = lens_of(session, lens, size)
        if K is None:   # no lens kept: start from its focal length, no distortion
            K = (lens.K if lens is not None else
                 np.array([[1.2 * max(size), 0, (size[0] - 1) / 2],
                           [0, 1.2 * max(size), (size[1] - 1) / 2], [0, 0, 1.0]]))
            dist = np.zeros(5)
        views = [(d.file, d.marker_ids, d.corners_mm, d.corners_for(*lens_of(session, lens, size)))
                 for d in ok if d.size_px == size]
        ap = estimate_as_printed(views, K, dist, size, lens_free=session.camera is None,
                                 config=config.as_printed)
        if ap is None:
            return None, lens, dets, None
        if not ap.rms_mm > config.as_printed.min_deviation_ratio * ap.unresolved_mm:
            # the views see no print off its layout beyond what they cannot resolve
            log.info("as printed: %.4f mm RMS off the layout, within %.4f mm the views leave "
                     "unresolved: the declared layout is kept", ap.rms_mm, ap.unresolved_mm)
            return None, lens, dets, ap
        if session.camera is None and lens is not None and lens.kept:
            lens = replace(lens, K=ap.K, dist=ap.dist)   # the held-out test kept a lens
    out = []
    for d in dets:
        if d.status != "ok" or not len(d.marker_ids):
            out.append(d)
            continue
        d2 = replace(d, corners_mm=ap.corners_for(d.marker_ids, d.corners_mm))
        d2.__dict__["_corners_memo"] = d.__dict__.get("_corners_memo", {})
        out.append(d2)
    return ap, lens, out, None


def print_stage(session: Session, images: list[ImageResult], as_printed: AsPrinted | None,
                config: EstimatorConfig, kept_declared: AsPrinted | None = None) -> dict | None:
    """measurement.json ``print``: the print's deviation from its layout and the limit it
    leaves on the marks (``limit_mm``, 2-D RMS). As printed (a survey or several places):
    its figures, the limit what the solve leaves on marks between the markers (the corners'
    uncertainty, the lens's and the poses', ``AsPrinted.limit_mm``; ``sigma_mm``: per
    axis, added to every mark's variance as below). Seen from several places but kept as
    declared (within what the views resolve): the deviation they saw beyond what they
    leave unresolved (RMS, in quadrature) is the limit. From one place, where the print cannot
    be told from the lens and the pose: each marker's mean corner residual beyond the
    photo's mapping (the part of the print a homography cannot take; RMS over the markers,
    less what the corners' own noise, seen within each marker, explains), times
    ``config.as_printed.single_view_factor`` for what it took; ``sigma_mm`` is then added to
    every mark's variance per axis."""
    if kept_declared is not None:
        # the views saw the print within what they cannot resolve: the declared layout is
        # kept, and what they saw of it beyond their own noise stays on every mark (issue
        # 37: four views of a print 0.3 mm off, unresolved 0.14 mm, added nothing and said
        # "ready" with marks 0.14 mm off)
        lim = float(np.sqrt(max(kept_declared.rms_mm ** 2 - kept_declared.unresolved_mm ** 2,
                                0.0)))
        return {"source": kept_declared.source, "applied": False,
                "rms_mm": kept_declared.rms_mm, "max_mm": kept_declared.max_mm,
                "unresolved_mm": kept_declared.unresolved_mm,
                "interior_mm": kept_declared.interior_mm, "limit_mm": lim,
                "sigma_mm": lim / np.sqrt(2.0),
                "height_rms_mm": kept_declared.height_rms_mm,
                "n_places": kept_declared.n_places}
    if as_printed is not None:
        return {"source": as_printed.source, "applied": True, "rms_mm": as_printed.rms_mm,
                "max_mm": as_printed.max_mm, "growth_mm": as_printed.growth_mm,
                "field_rms_mm": as_printed.field_rms_mm,
                "unresolved_mm": as_printed.unresolved_mm,
                "interior_mm": as_printed.interior_mm,
                "limit_mm": as_printed.limit_mm,
                "sigma_mm": as_printed.limit_mm / np.sqrt(2.0),
                "height_rms_mm": as_printed.height_rms_mm,
                "n_places": as_printed.n_places,
                **({"field": as_printed.field} if as_printed.field is not None else {})}
    declared = {int(m.id): np.asarray(m.corners_mm, float) for m in session.sheet.markers}
    means, noise = [], []
    for im in images:
        if im.status != "ok" or im.mapping is None or not len(im.marker_ids):
            continue
        xy = im.mapping.image_to_sheet(np.asarray(im.markers_px).reshape(-1, 2)).reshape(-1, 4, 2)
        dec = np.array([declared[int(i)] for i in im.marker_ids])
        r = xy - dec
        m = r.mean(axis=1)
        # within a marker: its growth (toner) along the corners' diagonals, then noise
        sgn = np.sign(dec - dec.mean(axis=1, keepdims=True))
        g = (((r - m[:, None]) * sgn).sum(axis=(1, 2)) / 8.0)[:, None, None]
        noise.append((r - m[:, None] - g * sgn).reshape(len(r), -1))
        means.append(m)
    if not means:
        return None
    seen = float(np.sqrt(np.mean(np.sum(np.concatenate(means) ** 2, axis=1))))
    # 8 values a marker, 3 taken (its mean, its growth): the corners' noise per axis, and
    # that of a marker's mean (2-D) is 2 sigma^2 / 4
    nz = np.concatenate(noise)
    s2 = float(np.sum(nz**2)) / max(nz.shape[0] * 5, 1)
    excess = float(np.sqrt(max(seen**2 - s2 / 2.0, 0.0)))
    limit = config.as_printed.single_view_factor * excess
    return {"source": "one place", "seen_rms_mm": excess, "corner_noise_mm": float(np.sqrt(s2)),
            "limit_mm": limit,
            "sigma_mm": limit / np.sqrt(2.0), "n_places": 1}


def print_field_cov(summary: dict | None, xy_mm) -> np.ndarray | None:
    """(2N, 2N) the marks' joint covariance the print leaves (measurement.json ``print``
    ``field``, :attr:`vision_cal.measure.asprinted.AsPrinted.field`) at positions ``xy_mm``
    (N, 2), rows x0, y0, x1, y1, ...: correlated between marks. None without a field."""
    f = (summary or {}).get("field")
    if not f:
        return None
    B = field_basis(np.asarray(xy_mm, float).reshape(-1, 2), f["centre_mm"], f["scale_mm"])
    return B @ np.asarray(f["cov_mm2"], float) @ B.T
