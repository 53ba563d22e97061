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
from vision_cal.measure.grid_print import GridPrint
from vision_cal.measure.mapping import LensEstimate
from vision_cal.measure.replicate import (APPLIED, FAILED, NOT_SIGNIFICANT, claim_of,
                                          stated_scale, with_replication)
from vision_cal.measure.types import ImageDetections, ImageResult

log = logging.getLogger(__name__)


def as_printed_stage(session: Session, dets: list[ImageDetections], lens: LensEstimate | None,
                     config: EstimatorConfig, *, survey: AsPrinted | None = None,
                     replicate_all: bool = False):
    """The sheet as printed (:mod:`vision_cal.measure.asprinted`): the survey's layout when
    one is given, else estimated from these photos when they were taken from at least
    ``config.as_printed.min_places`` places and off its layout beyond
    ``config.as_printed.min_deviation_ratio`` times what they leave unresolved (a survey
    that claims no field, :func:`vision_cal.measure.replicate.claim_of`, is returned as the
    layout found but not used). Returns
    (as_printed or None, lens, detections
    with their markers' corners as printed); an estimated lens is then the one solved with
    the layout (the stage-2 lens absorbed part of the print), when stage 2 kept one; and
    the layout found but not used (None when used or not found). The layout is replicated
    (:func:`vision_cal.measure.replicate.with_replication`) when it is significant, or
    always with ``replicate_all`` (a survey reports its halves whatever they say)."""
    ap = survey
    if ap is not None and not claim_of(ap, config.as_printed).applied:
        # a survey on its layout as far as its photos tell (not significant): the print is
        # measured, no field moves a mark (print_stage's kept_declared, issue 37)
        return None, lens, dets, ap
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
        # issue 37: the field again from two halves of the places, and applied only when
        # it converged, is significant and replicates (measure/replicate.claim_of)
        ap = with_replication(ap, views, K, dist, size, lens_free=session.camera is None,
                              config=config.as_printed, only_significant=not replicate_all)
        claim = claim_of(ap, config.as_printed)
        if not claim.applied:
            log.info("as printed: not applied (%s): %s", claim.status, claim.reason)
            return None, lens, dets, ap
        if session.camera is None and lens is not None and lens.kept:
            lens = replace(lens, K=ap.K, dist=ap.dist)   # the held-out test kept a lens
    out = []
    gp = GridPrint.from_as_printed(ap, config)   # the grid reference's correction (#37)
    for d in dets:
        if d.status != "ok" or not len(d.marker_ids):
            out.append(d)
            continue
        d2 = replace(d, corners_mm=ap.corners_for(d.marker_ids, d.corners_mm), grid_print=gp)
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
    every mark's variance per axis. A layout found from several places but not applied
    (``kept_declared``: its solve stopped, it is not significant or does not replicate,
    :func:`vision_cal.measure.replicate.claim_of`) moves no mark: its ``status`` and
    ``reason``, and the print's size is carried: as from one place, or what the views saw
    of it beyond what they cannot resolve when larger (issue 37: four views of a print 0.3
    mm off, unresolved 0.14 mm, added nothing and said "ready" with marks 0.14 mm off)."""
    if kept_declared is not None:
        return _not_applied(kept_declared, _beyond_mapping(session, images, config), config)
    if as_printed is not None:
        return _applied(as_printed, config)
    seen = _beyond_mapping(session, images, config)
    return None if seen is None else {"source": "one place", **seen, "n_places": 1}


def _applied(ap: AsPrinted, config: EstimatorConfig) -> dict:
    """measurement.json ``print`` of a layout applied (:func:`print_stage`). The halves'
    scatter beyond what each stated scales what the field leaves (``stated_scale``, #37).
    An undeclared lens solved with the print (``lens_free``): what it leaves between the
    markers, ``interior_mm``, is carried times ``config.as_printed.lens_free_interior_factor``
    (``interior_factor``; the limit, the marks' ``sigma_mm``, and the shared ``field`` as
    much as the limit grew: a declared lens, or an interior below the corners' own, changes
    nothing): the
    radial terms trade with what the solve does not model (the paper's shape between the
    markers, the edges' bias), the same in every photo and in both halves, so neither the
    Jacobian nor the halves show it (issue 37, world2: marks 0.036-0.073 mm off, limit 0.035,
    expected target error covering 7 of 10 seeds)."""
    k = stated_scale(ap.replication)
    inner = ap.interior_mm
    known = inner is not None and np.isfinite(inner)
    f = max(config.as_printed.lens_free_interior_factor, 1.0) if ap.lens_free and known else 1.0
    limit = max(ap.limit_mm, f * inner) if known else ap.limit_mm
    field = ap.field   # the shared part grows as the limit did
    scale2 = (k * (limit / ap.limit_mm if ap.limit_mm > 0 else 1.0)) ** 2
    if field is not None and scale2 > 1.0:
        field = {**field, "cov_mm2": (scale2 * np.asarray(field["cov_mm2"])).tolist()}
    return {"source": ap.source, "applied": True, "status": APPLIED,
            "rms_mm": ap.rms_mm, "max_mm": ap.max_mm, "growth_mm": ap.growth_mm,
            "field_rms_mm": ap.field_rms_mm, "unresolved_mm": ap.unresolved_mm,
            "interior_mm": inner, "limit_mm": k * limit, "sigma_mm": k * limit / np.sqrt(2.0),
            "height_rms_mm": ap.height_rms_mm, "n_places": ap.n_places,
            **({"lens_free": True, "interior_factor": f} if ap.lens_free and known else {}),
            **({"field": field} if field is not None else {}),
            **({"replication": ap.replication, "stated_scale": k}
               if ap.replication is not None else {})}


def _not_applied(ap: AsPrinted, seen: dict | None, config: EstimatorConfig) -> dict:
    """measurement.json ``print`` of a layout found but not applied (:func:`print_stage`)."""
    claim = claim_of(ap, config.as_printed)
    out = {"source": ap.source, "applied": False, **claim.to_json()}
    if claim.status != FAILED:   # a solve that stopped is no result: no figure of it
        out.update({"rms_mm": ap.rms_mm, "max_mm": ap.max_mm,
                    "unresolved_mm": ap.unresolved_mm, "height_rms_mm": ap.height_rms_mm,
                    "replication": ap.replication})
    out["n_places"] = ap.n_places
    out = {**out, **(seen or {"limit_mm": 0.0})}
    if claim.status != FAILED:
        out["interior_mm"] = ap.interior_mm
    if claim.status == NOT_SIGNIFICANT:   # on its layout as far as the views tell: what they
        # saw of it beyond what they cannot resolve stays on every mark (the others are not
        # a measured print: the verdict carries the size they found)
        views = float(np.sqrt(max(ap.rms_mm ** 2 - ap.unresolved_mm ** 2, 0.0)))
        if views > out.get("limit_mm", 0.0):
            out.update({"limit_mm": views, "sigma_mm": views / np.sqrt(2.0)})
    return out


def _beyond_mapping(session: Session, images: list[ImageResult], config: EstimatorConfig
                    ) -> dict | None:
    """The print as the photos' mappings leave it (:func:`print_stage`, from one place):
    ``seen_rms_mm``, ``corner_noise_mm``, ``limit_mm``, ``sigma_mm``; None without a
    photo measured."""
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
    return {"seen_rms_mm": excess, "corner_noise_mm": float(np.sqrt(s2)),
            "limit_mm": limit, "sigma_mm": limit / np.sqrt(2.0)}


def print_not_measured(summary: dict | None) -> bool:
    """Whether measurement.json ``print`` says the print is not measured (issue 37): from one
    place (no survey, photos from fewer than ``as_printed.min_places`` places), or a layout
    found but not applied for any reason but ``not significant`` (its solve stopped, it is
    not resolved or does not replicate: it tells nothing). No ``print`` block: False."""
    if not isinstance(summary, dict):
        return False
    if summary.get("source") == "one place":
        return True
    return (summary.get("applied") is False
            and summary.get("status") not in (None, "not significant"))


def unmeasured_print_size(summary: dict | None, config: EstimatorConfig) -> float:
    """The print's size (2-D RMS, mm) when it is not measured (:func:`print_not_measured`):
    the printer's prior (config ``uncertainty.unmeasured_print_mm``) at least, or the larger
    part the markers show beyond the photos' mapping (``limit_mm``), or what a layout found
    but not held saw (``rms_mm``). The verdict's print part and the covariance's prior."""
    def num(key):
        x = (summary or {}).get(key)
        return float(x) if isinstance(x, (int, float)) and np.isfinite(x) and x > 0 else 0.0
    found = num("rms_mm") if (summary or {}).get("source") != "one place" else 0.0
    return max(num("limit_mm"), found, config.uncertainty.unmeasured_print_mm)


def unmeasured_field_cov(xy_mm, extent_mm, rms_mm: float) -> np.ndarray:
    """(2N, 2N) the marks' joint covariance of a print not measured, at ``xy_mm`` (N, 2):
    a smooth field of the kind a photo's mapping takes (:func:`field_basis`, a homography's
    8 terms, in the paper's centre and half its larger side), its coefficients independent
    and alike, the best-fitting similarity over the paper removed (the markers define the
    sheet frame on average; the paper's scale is ``paper_scale``'s), sized so that its
    expected 2-D RMS over the paper ``extent_mm`` [x0, y0, x1, y1] is ``rms_mm`` (config
    ``uncertainty.unmeasured_print_mm``). Through one place's mapping the marks share it."""
    x0, y0, x1, y1 = (float(v) for v in extent_mm)
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    scale = max(x1 - x0, y1 - y0) / 2
    g = np.stack(np.meshgrid(np.linspace(x0, x1, 15), np.linspace(y0, y1, 15)), -1).reshape(-1, 2)
    Bg = field_basis(g, centre, scale)
    S = Bg[:, :6] @ np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, -1],
                              [0, 0, 0, 1], [0, 0, 1, 0]], float)   # shift, scale, turn
    resid = Bg - S @ np.linalg.lstsq(S, Bg, rcond=None)[0]   # each term less its similarity
    M = np.linalg.lstsq(Bg, resid, rcond=None)[0]             # (8, 8): c -> c less it
    k2 = rms_mm**2 * len(g) / max(float(np.sum(resid**2)), 1e-300)
    B = field_basis(np.asarray(xy_mm, float).reshape(-1, 2), centre, scale)
    return k2 * (B @ M) @ (B @ M).T


def print_shared_cov(summary: dict | None, xy_mm, extent_mm,
                     config: EstimatorConfig) -> np.ndarray | None:
    """(2N, 2N) what the print moves the marks at ``xy_mm`` by together: the measured
    field's (:func:`print_field_cov`), else, the print not measured
    (:func:`print_not_measured`) on a paper of known ``extent_mm``, the printer's prior
    (:func:`unmeasured_field_cov` of :func:`unmeasured_print_size`); None
    otherwise."""
    C = print_field_cov(summary, xy_mm)
    if C is not None or extent_mm is None or not print_not_measured(summary):
        return C
    return unmeasured_field_cov(xy_mm, extent_mm, unmeasured_print_size(summary, config))


def print_field_cov(summary: dict | None, xy_mm) -> np.ndarray | None:
    """(2N, 2N) the marks' joint covariance the print leaves (measurement.json ``print``
    ``field``, :attr:`vision_cal.measure.asprinted.AsPrinted.field`) at positions ``xy_mm``
    (N, 2), rows x0, y0, x1, y1, ...: correlated between marks. None without a field."""
    f = (summary or {}).get("field")
    if not f:
        return None
    B = field_basis(np.asarray(xy_mm, float).reshape(-1, 2), f["centre_mm"], f["scale_mm"])
    return B @ np.asarray(f["cov_mm2"], float) @ B.T
