"""Stage 2: the lens (``session.camera`` when declared; otherwise estimated jointly over the
photos of each image size and kept only when held-out marker corners say it helps,
:func:`lens_of_photos`), then per photo the final mapping (lens + homography) and each
dot's centre on the sheet with its covariance (:func:`finish_image`, :func:`finish_all`),
each dot refined in ``config.dots.views_per_dot`` photos and only seen in the others
(:mod:`vision_cal.measure.views`)."""

from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

import numpy as np

from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.dataset.session import Session
from vision_cal.errors import VisionCalError
from vision_cal.measure.detect import detect_image
from vision_cal.measure.dots import blank_regions, ground_scale, radii_mm, refine_dot
from vision_cal.measure.grid import grid_offset
from vision_cal.measure.grid_declaration import misdeclared_grid
from vision_cal.measure.grid_print import GridPrint, against_grid
from vision_cal.measure.height import camera_centre_mm
from vision_cal.measure.mapping import LensEstimate, estimate_lens, fit_mapping, undistort_px
from vision_cal.measure.photo_agreement import disagreeing_photos
from vision_cal.measure.previous_photo import previous_photos
from vision_cal.measure.printed import printed_reference
from vision_cal.measure.rotated import to_main_px, transposed, turned_lens
from vision_cal.measure.sheetfit import LENS_CAUSE, MISFIT, sheet_misfit
from vision_cal.measure.types import ImageDetections, ImageResult
from vision_cal.measure.views import ViewCount

log = logging.getLogger(__name__)


def lens_of(session: Session, lens: LensEstimate | None, size):
    """(K, dist) for a photo of ``size`` px: session.json's camera, else the estimated lens
    (turned for a photo of the same camera held the other way), else (None, None)."""
    if session.camera is not None:
        return session.camera.K, session.camera.dist
    if lens is not None and lens.kept and tuple(lens.size_px) == tuple(size):
        return lens.K, lens.dist
    if lens is not None and lens.kept and lens.turned and transposed(size, lens.size_px):
        return turned_lens(lens.K, lens.dist, lens.size_px, lens.turned)
    return None, None


def finish_image(det: ImageDetections, session: Session, lens: LensEstimate | None = None,
                 *, from_cache: bool = False, previous=None, ground_scale: float = 1.0,
                 refine=None, config: EstimatorConfig | None = None) -> ImageResult:
    """Stage 2: final mapping and dot centres on the sheet (``config``: the ``dots``
    thresholds, default ``vision_cal.config.DEFAULT``). ``previous``: the photo before
    in a series adding marks (:mod:`vision_cal.measure.previous_photo`);
    ``ground_scale``: the series' plain-ground level (:func:`dots.ground_scale`).
    ``refine``: which dot candidates to refine, a bool per candidate or a function of their
    sheet positions (K, 2), the photo's mapping and its K (None: no lens) giving them
    (:func:`_finish_views`); the others are only seen (``ImageResult.seen_xy_mm``). None or
    empty: every candidate."""
    config = config or DEFAULT
    if det.status != "ok":
        return ImageResult(det.file, det.status, det.reason, n_markers=len(det.marker_ids),
                           size_px=det.size_px, from_cache=from_cache)
    K, dist = lens_of(session, lens, det.size_px)
    corners_px = det.corners_for(K, dist)
    m = fit_mapping(det.corners_mm.reshape(-1, 2), corners_px.reshape(-1, 2), K=K, dist=dist)
    # the gate judges the corners where the mapping fits them: in ideal pixels
    ideal_px = (corners_px if K is None else
                undistort_px(corners_px.reshape(-1, 2), K, dist).reshape(corners_px.shape))
    misfit = sheet_misfit(det.corners_mm, ideal_px, m.corner_rms_mm,
                          float(np.median(m.mm_per_px(det.corners_mm.mean(axis=1)))),
                          size_px=det.size_px,
                          raw_px=((lambda: det.corners_for(None, None))
                                  if dist is not None and np.any(dist) else None),
                          config=config.sheet_fit)
    if misfit is not None:  # the markers do not fit the declared sheet
        return ImageResult(det.file, "skipped", misfit,
                           n_markers=len(det.marker_ids), corner_rms_px=m.corner_rms_px,
                           corner_rms_mm=m.corner_rms_mm, size_px=det.size_px,
                           from_cache=from_cache)
    c = det.candidates
    dia = session.pen_mark_diameter_mm
    xy0 = m.image_to_sheet(c.uv_px) if len(c.uv_px) else np.zeros((0, 2))
    want = (np.ones(len(xy0), bool) if refine is None or (not callable(refine) and not len(refine))
            else np.asarray(refine(xy0, m, K) if callable(refine) else refine, bool))
    seen_xy, seen_uv = [], []
    xs, covs, uvs, xg, offs, refs, gcov, ocov = [], [], [], [], [], [], [], []
    unrel, under, bgr, bgk, sus = [], [], [], [], []
    rejected = dict(c.rejected)
    blank = blank_regions(session.sheet)
    grid = session.sheet.grid_spec
    have_grid = grid is not None and det.grid_patches is not None
    pref = printed_reference(session.sheet)
    gprint = det.grid_print if det.grid_print is not None else GridPrint.unmeasured(config)
    # the local grid reference leaves out what is printed over or instead of the grid
    grid_blank = blank if pref is None else np.concatenate([blank, pref.ungridded_boxes_mm()])
    for k, (patch, org, x0, uv) in enumerate(zip(c.patches, c.origins, xy0, c.uv_px)):
        if not want[k]:   # refined in enough photos before this one
            seen_xy.append(x0)
            seen_uv.append(uv)
            continue
        r = refine_dot(patch, org, m, x0, dia_mm=dia, noise_sigma=c.noise_sigma,
                       blank_rects=blank, printed=pref, previous=previous,
                       ground_scale=ground_scale, config=config.dots)
        if r is None:
            rejected["not measurable"] = rejected.get("not measurable", 0) + 1
            continue
        xy, cov, off, ref = r.xy_mm, r.cov_mm2, np.full(2, np.nan), "markers"
        oc = np.full((2, 2), np.nan)
        if have_grid and not r.printed_under:   # over print, the grid around is interrupted
            go = _local_grid(det, k, m, r.xy_mm, grid, dia or config.dots.default_diameter_mm,
                             grid_blank, config)
            if go is not None:
                # the dot against the printed lines around it: the marker mapping's error
                # (and a raised paper's parallax) cancels, the lines' own noise adds; the
                # lines are where the printer put them: its displacement as the markers
                # measured it taken off, its uncertainty (the printer's prior when not
                # measured) added (measure/grid_print, issue 37)
                xy, cov, off, oc = against_grid(r.xy_mm, r.cov_noise_mm2, go, gprint)
                ref = "grid"
        xs.append(xy)
        covs.append(cov)
        uvs.append(uv)
        xg.append(r.xy_mm)
        offs.append(off)
        gcov.append(r.cov_mm2)
        ocov.append(oc)
        refs.append(ref)
        unrel.append(r.unreliable)
        under.append(r.printed_under)
        bgr.append(float(r.bg_residual))
        bgk.append(r.background)
        sus.append(r.suspect)
    return replace(ImageResult(det.file, "ok", None, len(det.marker_ids), m.corner_rms_px,
                       m.corner_rms_mm, len(xs), np.asarray(xs).reshape(-1, 2),
                       np.asarray(covs).reshape(-1, 2, 2), np.asarray(uvs).reshape(-1, 2),
                       rejected, c.noise_sigma, det.size_px, from_cache,
                       np.asarray(det.marker_ids), det.corners_for(K, dist),
                       np.asarray(xg).reshape(-1, 2), np.asarray(offs).reshape(-1, 2),
                       tuple(refs), np.asarray(gcov).reshape(-1, 2, 2),
                       np.asarray(ocov).reshape(-1, 2, 2), m, K, tuple(unrel), tuple(under)),
                   dots_bg_residual=tuple(bgr), dots_background=tuple(bgk),
                   dots_suspect=tuple(sus), seen_xy_mm=np.asarray(seen_xy).reshape(-1, 2),
                   seen_uv_px=np.asarray(seen_uv).reshape(-1, 2))


def _local_grid(det: ImageDetections, k: int, mapping, xy_mm, grid, dia, blank, config):
    """The printed grid's offset around candidate ``k`` (None: not usable)."""
    if k >= len(det.grid_patches):
        return None
    r_win, _ = radii_mm(float(dia), float(mapping.mm_per_px(xy_mm)[0]))
    return grid_offset(det.grid_patches[k], det.grid_origins[k], mapping, xy_mm, grid,
                       exclude_r_mm=r_win, blank_rects=blank, dot_dia_mm=dia,
                       dots=config.dots, config=config.grid)


def _check_sheet_fits(session: Session, images: list[ImageResult]) -> None:
    """Stop when most photos say the markers do not fit the declared sheet: then the sheet
    is typed wrong (corner order, marker size, dictionary), not the photos bad."""
    misfit = [r for r in images if r.status != "ok" and (r.reason or "").startswith(MISFIT)]
    if not misfit or 2 * len(misfit) <= len(images):
        return
    typical = sorted(misfit, key=lambda r: r.corner_rms_mm)[len(misfit) // 2]
    lens = f"likely cause: {LENS_CAUSE}" in typical.reason  # the lens, not the sheet
    raise VisionCalError(f"the markers do not fit the declared sheet in {len(misfit)} of "
                         f"{len(images)} photos ({typical.file}: "
                         f"{typical.reason[len(MISFIT) + 2:]})",
                         file=str(session.path), field="camera.dist" if lens else "sheet.markers")


def lens_of_photos(session: Session, dets: list[ImageDetections]
                   ) -> tuple[LensEstimate | None, list[str]]:
    """Stage 2: the lens, estimated over the photos of the commonest size (and the same
    camera turned) when session.json declares no camera. Returns (lens or None, warnings)."""
    if session.camera is not None:
        return None, []
    ok = [d for d in dets if d.status == "ok"]
    sizes = sorted({d.size_px for d in ok}, key=lambda s: -sum(x.size_px == s for x in ok))
    if not sizes:
        return None, []
    size = sizes[0]
    views = [(d.marker_ids, d.corners_mm, d.corners_for()) for d in ok if d.size_px == size]
    turned = [d for d in ok if transposed(d.size_px, size)]
    if turned:   # the same camera held the other way: one lens, fitted over all
        best = None
        for turn in (1, -1):
            est = estimate_lens(views + [(d.marker_ids, d.corners_mm,
                                          to_main_px(d.corners_for(), size, turn))
                                         for d in turned], size)
            if est is not None and (best is None or est.rms_px_after < best[0].rms_px_after):
                best = (est, turn)
        lens = None if best is None else replace(best[0], turned=best[1])
    else:
        lens = estimate_lens(views, size)
    rest = [s for s in sizes[1:] if not transposed(s, size)]
    warnings = []
    if rest:
        warnings.append(f"photos of {len(rest) + 1} image sizes: a lens is estimated "
                        f"only for {size[0]}x{size[1]} px"
                        + (" (and the same camera turned)" if turned else ""))
    return lens, warnings


def finish_all(session: Session, dets: list[ImageDetections], cached: list[bool],
               lens: LensEstimate | None, config: EstimatorConfig | None = None, *,
               listed_marks=None
               ) -> tuple[list[ImageResult], list[str]]:
    """Every photo's final mapping and dots (:func:`finish_image`), each dot refined in
    ``config.dots.views_per_dot`` photos (:mod:`vision_cal.measure.views`); the sheet's
    declaration checked (markers that do not fit it stop the run, a misdeclared grid is
    dropped: the markers win), the photo before as the print under new marks
    (``listed_marks``: per photo the marks session.json lists, None when not listed;
    :mod:`vision_cal.measure.previous_photo`) and a photo moved as a whole against the
    others left out (when it held views other photos then skipped, the views are counted
    again without it). Returns (images, warnings)."""
    config = config or DEFAULT
    images, warnings = _finish_series(session, dets, cached, lens, config, listed_marks)
    out = disagreeing_photos(images, config.photo_agreement)
    if any(images[k].n_dots for k in out) and any(len(im.seen_xy_mm) for im in images):
        images, warnings = _finish_series(session, dets, cached, lens, config, listed_marks,
                                          not_counted=set(out))
    # a photo moved as a whole against the others is left out, not the marks it shares
    for k, why in out.items():
        log.warning("%s: %s", images[k].file, why)
        warnings.append(f"{images[k].file}: {why}")
        images[k] = replace(images[k], status="skipped", reason=why)
    return images, warnings


def _finish_views(session: Session, dets, cached, lens, config: EstimatorConfig,
                  not_counted=frozenset()) -> tuple[list[ImageResult], list]:
    """The first finish of every photo, in capture order, each dot refined until it has
    ``config.dots.views_per_dot`` reliable views (photos in ``not_counted`` give none).
    Returns (images, per photo which candidates were refined: for the reruns; None: all)."""
    ac = config.association
    dia = session.pen_mark_diameter_mm or config.dots.default_diameter_mm
    views = ViewCount(config.dots.views_per_dot,
                      max(ac.group_tol_diameters * dia, ac.group_tol_min_mm),
                      config.sheet_height.same_place_fraction)
    images, chosen = [], []
    for k, (d, c) in enumerate(zip(dets, cached)):
        picked, place = [], []

        def wanted(xy_mm, mapping, K, picked=picked, place=place):
            place.append(views.place(_camera_centre(mapping, K)))
            picked.append(views.wanted(xy_mm, place[0]))
            return picked[0]

        im = finish_image(d, session, lens, from_cache=c,
                          refine=None if k in not_counted else wanted, config=config)
        if im.status == "ok" and k not in not_counted and place:
            views.add(im.dots_xy_mm, [not u for u in im.dots_unreliable], place[0])
        images.append(im)
        chosen.append(picked[0] if picked else None)
    return images, chosen


def _camera_centre(mapping, K):
    """The camera's centre (3,) in the sheet frame, None without a lens or a pose."""
    if K is None:
        return None
    try:
        return camera_centre_mm(mapping.H_img_sheet, K)
    except (VisionCalError, np.linalg.LinAlgError):
        return None


def _finish_series(session: Session, dets, cached, lens, config: EstimatorConfig,
                   listed_marks, not_counted=frozenset()) -> tuple[list[ImageResult], list[str]]:
    """:func:`finish_all` but for the photos moved as a whole (the same arguments)."""
    warnings: list[str] = []
    images, chosen = _finish_views(session, dets, cached, lens, config, not_counted)
    _check_sheet_fits(session, images)
    wrong_grid = misdeclared_grid(images, session.sheet.grid_spec, config.grid_declaration,
                                  height_config=config.sheet_height)
    if wrong_grid is not None:   # two references disagree by a constant: the markers win
        log.warning(wrong_grid.message)
        warnings.append(wrong_grid.message)
        session = replace(session, sheet=replace(session.sheet, grid=None))
        images = [finish_image(d, session, lens, from_cache=c, refine=r, config=config)
                  for d, c, r in zip(dets, cached, chosen)]

    # the tests for ink under a mark against this series' plain ground, not the blank
    # paper's noise (JPEG, grid lines a few pixels apart, a low resolution)
    ok = [im for im in images if im.status == "ok"]
    g = ground_scale([x for im in ok for x in im.dots_bg_residual],
                     [b for im in ok for b in im.dots_background],
                     [u for im in ok for u in im.dots_printed_under], config.dots)
    if g > 1.0:
        images = [finish_image(d, session, lens, from_cache=c, ground_scale=g, refine=r,
                               config=config)
                  if any(im.dots_unreliable) else im
                  for d, c, im, r in zip(dets, cached, images, chosen)]

    # a series adding marks photo by photo, on a sheet whose print is not described: the
    # photo before shows the print under each new mark
    if listed_marks is not None and printed_reference(session.sheet) is None:
        # refine_dot uses it only for dots paper and grid lines leave unreliable or not
        # measurable: the other photos are neither decoded again nor finished twice
        need = {k for k, im in enumerate(images)
                if any(im.dots_unreliable) or any(im.dots_suspect)
                or im.rejected.get("not measurable")}
        before = previous_photos(session, Path(session.root), [d.file for d in dets],
                                 listed_marks, images, only=need)
        for k, prev in before.items():
            images[k] = finish_image(dets[k], session, lens, from_cache=cached[k],
                                     previous=prev, ground_scale=g, refine=chosen[k],
                                     config=config)
    return images, warnings
