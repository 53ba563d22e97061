"""Measuring a dataset folder: every photo, every pen mark, in sheet millimetres.

Pipeline (``measure_folder``):

1. per photo, in parallel and cached by content (:func:`detect_image`): decode, find the
   sheet's ArUco markers, an approximate homography, ink-dot candidates with small raw
   patches (``vision_cal.measure.dots``). A bad photo is *skipped* with a one-line reason;
   the batch goes on.
2. the lens: ``session.camera`` when declared; otherwise estimated jointly over the photos
   of each image size and kept only when held-out marker corners say it helps
   (``vision_cal.measure.mapping.estimate_lens``), reported as ``lens_distortion``.
3. per photo: the final mapping (lens + homography) and each dot's centre on the sheet with
   its covariance.
4. association of dots to plan marks and the combined estimate of each mark
   (``vision_cal.measure.associate``), then the sheet's height (``vision_cal.measure.height``).

Each stage is one function (:func:`measure_folder` lists them); what they return are the
types of :mod:`vision_cal.measure.types`, and ``OUT/measurement.json`` is
``Measurement.to_json``. Nothing is ever written into the input folder: results and the
cache go to ``out_dir``.
"""

from __future__ import annotations

import hashlib
import logging
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from datetime import datetime
from pathlib import Path

import cv2
import numpy as np

from vision_cal.config import DEFAULT, AssociationConfig, EstimatorConfig, PlanMatchConfig
from vision_cal.dataset import photos
from vision_cal.dataset.io import atomic_write_json
from vision_cal.dataset.session import Session, load_session
from vision_cal.calibrate.tool import fit_tool
from vision_cal.errors import VisionCalError
from vision_cal.measure import associate as assoc
from vision_cal.measure.aruco import edge_points, find_sheet_markers
from vision_cal.measure.asprinted import AsPrinted, estimate_as_printed
from vision_cal.measure.cache import DetectionCache, cache_key, session_fingerprint
from vision_cal.measure.infer import infer_image_marks
from vision_cal.dataset.marker_geometry import marker_geometry
from vision_cal.measure.dots import (_radii_mm, blank_regions, find_candidates, ground_scale,
                                     refine_dot)
from vision_cal.measure.previous_photo import previous_photos
from vision_cal.measure.printed import printed_reference
from vision_cal.measure.rotated import to_main_px, transposed, turned_lens
from vision_cal.measure.sheetfit import LENS_CAUSE, MISFIT, sheet_misfit
from vision_cal.measure.grid import grid_offset
from vision_cal.measure.grid_declaration import misdeclared_grid
from vision_cal.measure.height import sheet_heights
from vision_cal.measure.mapping import LensEstimate, estimate_lens, fit_mapping, undistort_px
from vision_cal.measure.photo_agreement import disagreeing_photos
from vision_cal.measure.plan_match import check_plan_match
from vision_cal.measure.workers import exit_with_parent
from vision_cal.plan.orient import equivalent_joints
from vision_cal.progress import bar as progress_bar
from vision_cal.measure.types import (ImageDetections, ImageResult, MarkMeasurement, Measurement,
                                      dot_field)

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = set(photos.PHOTO_SUFFIXES)


# --------------------------------------------------------------------------- stage 1

def _skip(file, why, size=None) -> ImageDetections:
    return ImageDetections(file, "skipped", why, size)


def _decode(data: bytes, file: str, camera_size_px=None):
    """(BGR pixels, None) or (None, reason). The header is read and checked first, so a
    decompression bomb is refused before any pixel is decoded
    (:func:`vision_cal.dataset.photos.check_header`)."""
    if not data:
        return None, "unreadable: empty file"
    try:
        photos.check_complete(data)  # by its structure: a phone's trailer is not truncation
        turned = photos.check_header(photos.read_header(data), camera_size_px)
    except photos.PhotoRefused as e:
        return None, _refusal(file, e)
    img = photos.decode_photo(data, turned=turned)
    if img is None:
        return None, "unreadable: not an image OpenCV can decode"
    return img, None  # BGR: the dot stages only use channel max and sum (order-free)


def _drop_deformed_markers(d: ImageDetections, K, dist, *, min_markers: int | None = None,
                           min_px: float = 0.5,
                           factor: float = 5.0):
    """Leave out markers whose corners do not fit the sheet's shape (a corner on the arm's
    edge, a marker half hidden): residuals of a homography fitted to all markers, with each
    marker's mean residual removed (so that an undeclared lens, smooth over a marker, does
    not count), above ``max(min_px, factor x median)``. Returns (detections, n dropped)."""
    min_markers = DEFAULT.markers.min_markers if min_markers is None else min_markers
    n_drop = 0
    for _ in range(3):
        M = len(d.marker_ids)
        if M < min_markers + 1:
            break
        c = d.corners_for(K, dist)
        uv = undistort_px(c.reshape(-1, 2), K, dist).reshape(-1, 4, 2)
        H, _ = cv2.findHomography(d.corners_mm.reshape(-1, 2), uv.reshape(-1, 2), 0)
        if H is None:
            break
        pred = (d.corners_mm.reshape(-1, 2) @ H[:, :2].T + H[:, 2])
        pred = (pred[:, :2] / pred[:, 2:3]).reshape(-1, 4, 2)
        r = uv - pred
        r -= r.mean(axis=1, keepdims=True)
        rms = np.sqrt(np.mean(np.sum(r**2, axis=2), axis=1))
        bad = rms > max(min_px, factor * float(np.median(rms)))
        if not bad.any():
            break
        n_drop += int(bad.sum())
        d = d.keep_markers(~bad)
    return d, n_drop


def detect_image_bytes(data: bytes, file: str, session: Session, *,
                       config: EstimatorConfig | None = None) -> ImageDetections:
    """Stage 1 on one photo's bytes (pure function of its inputs; ``config``: the
    ``markers`` and ``dots`` thresholds, default ``vision_cal.config.DEFAULT``)."""
    config = config or DEFAULT
    cam = session.camera
    rgb, why = _decode(data, file, None if cam is None else cam.size_px)
    if rgb is None:
        return _skip(file, why)
    h, w = rgb.shape[:2]
    size = (int(w), int(h))
    if cam is not None and tuple(cam.size_px) != size:
        return _skip(file, f"wrong size: {w}x{h} px, camera.size_px says "
                           f"{cam.size_px[0]}x{cam.size_px[1]}", size)
    gray = cv2.cvtColor(rgb, cv2.COLOR_BGR2GRAY)
    if float(gray[::4, ::4].std()) < config.markers.blank_photo_std:
        return _skip(file, "blank image: no contrast", size)
    det = find_sheet_markers(gray, session.sheet, config=config.markers)
    if det.reason:
        return ImageDetections(file, "skipped", det.reason, size, det.ids, det.corners_px,
                               det.corners_mm)
    K = None if cam is None else cam.K
    dist = None if cam is None else cam.dist
    out = ImageDetections(file, "ok", None, size, det.ids, det.corners_px, det.corners_mm,
                          None, edge_points(gray, det.corners_px,
                                            geometry=marker_geometry(session.sheet)))
    out, n_bad = _drop_deformed_markers(out, K, dist, min_markers=config.markers.min_markers)
    if len(out.marker_ids) < config.markers.min_markers:
        return _skip(file, f"too few markers: {len(out.marker_ids)} usable after {n_bad} "
                           "deformed ones (partly hidden?) were left out", size)
    try:
        approx = fit_mapping(out.corners_mm.reshape(-1, 2),
                             out.corners_for(K, dist).reshape(-1, 2), K=K, dist=dist)
    except VisionCalError as e:
        return _skip(file, f"no mapping: {e.reason}", size)
    cand = find_candidates(rgb, approx, session.sheet, dia_mm=session.pen_mark_diameter_mm,
                           config=config.dots)
    gp, go = None, None
    if session.sheet.grid_spec is not None and len(cand.uv_px):
        gp, go = _grid_patches(rgb, approx, cand.uv_px, config.grid.window_half_mm)
    out = out.with_candidates(cand)
    if gp is None:
        return out
    out2 = replace(out, grid_patches=gp, grid_origins=go)
    out2.__dict__["_corners_memo"] = out.__dict__.get("_corners_memo", {})
    return out2


def _grid_patches(rgb, mapping, uv_px, half_mm: float):
    """uint16 R+G+B patches around each candidate wide enough for the local grid window
    (``half_mm``: its half-size, config ``grid.window_half_mm``)."""
    H, W = rgb.shape[:2]
    xy = mapping.image_to_sheet(uv_px)
    mmpp = mapping.mm_per_px(xy)
    patches, origins = [], []
    for (u, v), mpp in zip(uv_px, mmpp):
        hp = int(np.ceil(1.2 * (half_mm + 0.5) / max(float(mpp), 1e-6))) + 2
        cu, cv_ = int(round(u)), int(round(v))
        c0, r0 = max(cu - hp, 0), max(cv_ - hp, 0)
        c1, r1 = min(cu + hp + 1, W), min(cv_ + hp + 1, H)
        patches.append(rgb[r0:r1, c0:c1].astype(np.uint16).sum(axis=2, dtype=np.uint16))
        origins.append((c0, r0))
    return tuple(patches), np.asarray(origins, int).reshape(-1, 2)


def detect_image(path, session: Session, *, root=None, name: str | None = None,
                 sha256: str | None = None,
                 config: EstimatorConfig | None = None) -> ImageDetections:
    """Stage 1 on one photo file: ``root``/``name`` (``name`` the photo's relative path,
    kept in the result), or ``path`` itself. ``sha256``: the content the caller checked
    (header, cache key); a file that changed since is skipped."""
    path = Path(path)
    root = Path(root) if root is not None else path.parent
    name = name if name is not None else path.name
    try:
        data = photos.read_photo(root, name)
    except photos.PhotoRefused as e:
        return _skip(name, e.reason)
    if sha256 is not None and hashlib.sha256(data).hexdigest() != sha256:
        return _skip(name, "changed while being measured: run again")
    return detect_image_bytes(data, name, session, config=config)


# --------------------------------------------------------------------------- stage 2

def _lens_of(session: Session, lens: LensEstimate | None, size):
    if session.camera is not None:
        return session.camera.K, session.camera.dist
    if lens is not None and lens.kept and tuple(lens.size_px) == tuple(size):
        return lens.K, lens.dist
    if lens is not None and lens.kept and lens.turned and transposed(size, lens.size_px):
        return turned_lens(lens.K, lens.dist, lens.size_px, lens.turned)
    return None, None


def finish_image(det: ImageDetections, session: Session, lens: LensEstimate | None = None,
                 *, from_cache: bool = False, previous=None, ground_scale: float = 1.0,
                 config: EstimatorConfig | None = None) -> ImageResult:
    """Stage 2: final mapping and dot centres on the sheet (``config``: the ``dots``
    thresholds, default ``vision_cal.config.DEFAULT``). ``previous``: the photo before
    in a series adding marks (:mod:`vision_cal.measure.previous_photo`);
    ``ground_scale``: the series' plain-ground level (:func:`dots.ground_scale`)."""
    config = config or DEFAULT
    if det.status != "ok":
        return ImageResult(det.file, det.status, det.reason, n_markers=len(det.marker_ids),
                           size_px=det.size_px, from_cache=from_cache)
    K, dist = _lens_of(session, lens, det.size_px)
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
    xs, covs, uvs, xg, offs, refs, gcov, ocov = [], [], [], [], [], [], [], []
    unrel, under, bgr, bgk, sus = [], [], [], [], []
    rejected = dict(c.rejected)
    blank = blank_regions(session.sheet)
    grid = session.sheet.grid_spec
    have_grid = grid is not None and det.grid_patches is not None
    pref = printed_reference(session.sheet)
    # the local grid reference leaves out what is printed over or instead of the grid
    grid_blank = blank if pref is None else np.concatenate([blank, pref.ungridded_boxes_mm()])
    for k, (patch, org, x0, uv) in enumerate(zip(c.patches, c.origins, xy0, c.uv_px)):
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
                # (and a raised paper's parallax) cancels, the lines' own noise adds
                xy, off, ref = r.xy_mm - go.d_mm, go.d_mm, "grid"
                cov = r.cov_noise_mm2 + go.cov_mm2
                oc = go.cov_mm2
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
                   dots_suspect=tuple(sus))


def _local_grid(det: ImageDetections, k: int, mapping, xy_mm, grid, dia, blank, config):
    """The printed grid's offset around candidate ``k`` (None: not usable)."""
    if k >= len(det.grid_patches):
        return None
    r_win, _ = _radii_mm(float(dia), float(mapping.mm_per_px(xy_mm)[0]))
    return grid_offset(det.grid_patches[k], det.grid_origins[k], mapping, xy_mm, grid,
                       exclude_r_mm=r_win, blank_rects=blank, dot_dia_mm=dia,
                       dots=config.dots, config=config.grid)


def measure_image(path, session: Session, *, lens: LensEstimate | None = None,
                  config: EstimatorConfig | None = None) -> ImageResult:
    """Measure one photo (markers, mapping, dots in sheet mm). Pure; the result pickles."""
    return finish_image(detect_image(path, session, config=config), session, lens,
                        config=config)


# --------------------------------------------------------------------------- batch

def _worker(args):
    root, name, session, sha, config = args
    return detect_image(Path(root) / name, session, root=root, name=name, sha256=sha,
                        config=config)


def _is_inside(a: Path, b: Path) -> bool:
    try:
        a.resolve().relative_to(b.resolve())
        return True
    except ValueError:
        return False


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


@dataclass
class _Photo:
    """One photo before stage 1: its name, and what the parent learnt from its header."""

    file: str
    listed_marks: tuple | None
    det: ImageDetections | None = None
    sha256: str | None = None
    captured: object = None
    pixels: int = 0
    key: str | None = None
    cached: bool = False


def _refusal(file: str, e: "photos.PhotoRefused") -> str:
    """The reason a photo is refused; a camera format not read (HEIC, raw) says so and how
    to fix it, listed in session.json or found in the folder alike."""
    if e.reason.startswith("unreadable: not an image") and file.lower().endswith(
            photos.UNREAD_SUFFIXES):
        return (f"a {file.rsplit('.', 1)[-1].upper()} file, a format not read: convert it to "
                "JPEG or PNG")
    return e.reason


def _check_photo(ph: _Photo, root: Path, session: Session) -> None:
    """Read the photo once in the parent, before any worker sees it: regular file inside
    the folder, header within the limits (no pixel decoded). Fills ``sha256``, ``captured``
    or a skip (``det``)."""
    cam = session.camera
    try:
        data = photos.read_photo(root, ph.file)
        if not data:
            raise photos.PhotoRefused("unreadable: empty file")
        header = photos.read_header(data)
        photos.check_header(header, None if cam is None else cam.size_px)
    except photos.PhotoRefused as e:
        ph.det = _skip(ph.file, _refusal(ph.file, e))
        return
    ph.sha256 = hashlib.sha256(data).hexdigest()
    ph.captured = header.captured
    ph.pixels = header.stored_px[0] * header.stored_px[1]


def _capture_order(items: list[_Photo], warnings: list) -> list[_Photo]:
    """Photos found in the folder: by EXIF capture time when every readable photo has one,
    else by natural file name (already the order of ``items``)."""
    readable = [p for p in items if p.det is None]
    timed = [p for p in readable if p.captured is not None]
    if readable and len(timed) == len(readable):
        rank = {id(p): i for i, p in enumerate(items)}
        return sorted(items, key=lambda p: (p.captured is None, p.captured or datetime.min,
                                            rank[id(p)]))
    if timed:
        warnings.append(f"{len(readable) - len(timed)} of {len(readable)} photos have no EXIF "
                        "capture time: all are ordered by file name")
    return items


#: pixels decoded at once over all workers: each photo is at most ``photos.MAX_PIXELS``
#: (100 MP), and the workers together may not multiply that by more than two
MAX_PIXELS_IN_FLIGHT = 2 * photos.MAX_PIXELS


def jobs_for(jobs: int, pixels) -> int:
    """Worker count for photos of ``pixels`` each (from their headers): ``jobs``, reduced
    so that the largest photos decoded at once stay within :data:`MAX_PIXELS_IN_FLIGHT`."""
    biggest = max(pixels, default=0)
    if biggest <= 0:
        return max(1, jobs)
    return max(1, min(jobs, MAX_PIXELS_IN_FLIGHT // biggest))


def _pool_initializer(parent_pid: int) -> None:
    exit_with_parent(parent_pid)


def _tool_joints(params, tool_mm, session):
    """(joints (N, 2), the tool-less model they are for): the association predicts with a
    tool-less model, so each mark gets the joints that put it where ``params`` with
    ``tool_mm`` puts the pen. That model is ``params`` with L2 lengthened by |tool|, which
    reaches every pen position (``params`` itself does not reach a mark the tool puts
    beyond L1 + L2); the commanded joints where no such pose exists."""
    model = replace(params, L2_mm=params.L2_mm + float(np.hypot(*tool_mm)))
    q = session.joints_deg
    eq = equivalent_joints(params, tool_mm, q, session.j4_deg, solve_with=model)
    return np.where(np.isfinite(eq), eq, q), model


def _with_fitted_tool(a, session, mark_ids, mark_images, groups, ac):
    """The association again, predicted from the base model and tool fitted to the marks
    the first pass matched (robustly: a swapped pair is left out), when that matches at
    least as many marks. The robot file's rough ``tool_mm`` (millimetres off) turns with
    joint 4, which a tool-less model cannot follow: its residual widens the gates until
    marks a dozen millimetres apart are refused or swapped."""
    k = [list(mark_ids).index(mid) for mid in a.mark_to_group]
    if len(k) < 8:
        return a
    xy = np.array([groups[g].mean_mm for g in a.mark_to_group.values()])
    tf = fit_tool(session.joints_deg[k], session.j4_deg[k], xy)
    if not tf:
        return a
    q, model = _tool_joints(tf.fit.params, tf.tool_mm, session)
    b = assoc.associate(q, mark_ids, mark_images, groups, model,
                        max_zero_deg=ac.max_zero_deg, max_base_mm=ac.max_base_mm)
    return b if len(b.mark_to_group) >= len(a.mark_to_group) else a


def measure_folder(session, *, out_dir, jobs: int | None = None, cache_dir=None,
                   progress=None, config: EstimatorConfig | None = None,
                   survey: AsPrinted | None = None) -> Measurement:
    """Measure every photo of a dataset folder and every pen mark on the sheet.

    ``session``: a :class:`Session` or a folder. ``out_dir``: where results go (never the
    input folder); the cache defaults to ``out_dir/.cache``. ``jobs``: worker processes
    (default ``os.cpu_count()``; 1 runs in this process). ``progress``: a tqdm bar on stderr.
    ``config``: the thresholds of every stage (default ``vision_cal.config.DEFAULT``).
    Without ``images`` in session.json every photo in the folder is measured and which
    marks each shows is inferred (:mod:`vision_cal.measure.infer`). ``survey``: the sheet
    as printed (``vision-cal survey``'s survey.json): the marks are measured against it.

    The stages, one function each: :func:`photos_to_measure` (listing and checks),
    :func:`detect_all` (stage 1, cached, parallel), :func:`lens_of_photos` (stage 2),
    :func:`finish_all` (mapping and dots per photo), :func:`associate_dots` (stage 3),
    :func:`mark_measurements`, :func:`sheet_height_stage` (stage 4); measurement.json is
    written last.
    """
    if not isinstance(session, Session):
        session = load_session(session)
    if session.sheet is None:
        raise VisionCalError("no sheet: photos cannot be measured", file=str(session.path),
                             field="sheet")
    root = Path(session.root)
    out_dir = Path(out_dir)
    if _is_inside(out_dir, root):
        raise VisionCalError("the output folder must not be inside the input folder "
                             "(photos are never written to)", file=str(out_dir))
    cache = DetectionCache(Path(cache_dir) if cache_dir else out_dir / ".cache")
    config = config or DEFAULT
    ac = config.association

    items, warnings, notes = photos_to_measure(session)
    warnings += detect_all(items, session, cache, jobs=jobs, progress=progress, config=config)
    dets = [ph.det for ph in items]
    cached = [ph.cached for ph in items]
    lens, lens_warnings = lens_of_photos(session, dets)
    warnings += lens_warnings
    as_printed, lens, dets, kept_declared = as_printed_stage(session, dets, lens, config,
                                                             survey=survey)
    images, finish_warnings = finish_all(session, dets, cached, lens, config,
                                         listed_marks=[ph.listed_marks for ph in items])
    warnings += finish_warnings
    print_summary = print_stage(session, images, as_printed, config, kept_declared)
    files = [ph.file for ph in items]
    dots = associate_dots(session, items, images, ac, config.dots.default_diameter_mm,
                          config.plan_match)
    warnings += dots.warnings
    marks = mark_measurements(dots, images, files, ac)
    heights, hmap, hnote = sheet_height_stage(session, images, marks, dots, lens, config)
    for r in images:
        if r.status != "ok":
            log.info("skipped %s: %s", r.file, r.reason)
    inferred = dots.inferred
    meas = Measurement(marks, images, lens, dots.unassigned(files), dict(dots.assoc.refused),
                       warnings, tuple(dots.image_marks),
                       None if inferred is None else inferred.mode,
                       () if inferred is None else (*notes, *inferred.warnings),
                       heights, hmap, hnote, str(root.resolve()), as_printed, print_summary)
    if print_summary is not None and np.isfinite(print_summary.get("sigma_mm", np.nan)):
        marks = {k: replace(m, cov_mm2=m.cov_mm2 + print_summary["sigma_mm"] ** 2 * np.eye(2))
                 for k, m in meas.marks.items()}
        meas = replace(meas, marks=marks)
    atomic_write_json(out_dir / "measurement.json", meas.to_json())
    return meas


# --------------------------------------------------------------------------- the print (#28)

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
        K, dist = _lens_of(session, lens, size)
        if K is None:   # no lens kept: start from its focal length, no distortion
            K = (lens.K if lens is not None else
                 np.array([[1.2 * max(size), 0, (size[0] - 1) / 2],
                           [0, 1.2 * max(size), (size[1] - 1) / 2], [0, 0, 1.0]]))
            dist = np.zeros(5)
        views = [(d.file, d.marker_ids, d.corners_mm, d.corners_for(*_lens_of(session, lens, size)))
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
    its figures, the limit the corners' uncertainty (``sigma_mm``: per axis, added to every
    mark's variance as below). From one place, where the print cannot
    be told from the lens and the pose: each marker's mean corner residual beyond the
    photo's mapping (the part of the print a homography cannot take; RMS over the markers,
    less what the corners' own noise, seen within each marker, explains), times
    ``config.as_printed.single_view_factor`` for what it took; ``sigma_mm`` is then added to
    every mark's variance per axis."""
    if kept_declared is not None:   # the views saw the print on its layout: nothing added
        return {"source": kept_declared.source, "applied": False,
                "rms_mm": kept_declared.rms_mm, "max_mm": kept_declared.max_mm,
                "unresolved_mm": kept_declared.unresolved_mm, "limit_mm": 0.0,
                "height_rms_mm": kept_declared.height_rms_mm,
                "n_places": kept_declared.n_places}
    if as_printed is not None:
        return {"source": as_printed.source, "applied": True, "rms_mm": as_printed.rms_mm,
                "max_mm": as_printed.max_mm, "growth_mm": as_printed.growth_mm,
                "field_rms_mm": as_printed.field_rms_mm,
                "unresolved_mm": as_printed.unresolved_mm,
                "limit_mm": as_printed.unresolved_mm,
                "sigma_mm": as_printed.unresolved_mm / np.sqrt(2.0),
                "height_rms_mm": as_printed.height_rms_mm,
                "n_places": as_printed.n_places}
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


def photos_to_measure(session: Session) -> tuple[list[_Photo], list[str], list[str]]:
    """The photos to measure, in order (listed in session.json, or found in the folder by
    capture time), each read once and checked here before any worker sees it; a repeated
    file is skipped. Returns (photos, warnings, notes: what the console should see when
    session.json lists no images)."""
    root = Path(session.root)
    warnings: list[str] = []
    notes: list[str] = []
    try:
        present = photos.list_photos(root)
    except OSError as e:
        if not session.images_listed:
            raise VisionCalError(f"cannot list the photos: {e.strerror or e}",
                                 file=str(root)) from e
        present = []
    if session.images_listed:
        items = [_Photo(im.file, im.marks) for im in session.images]
        listed = {im.file for im in session.images}
        extra = [f for f in present if f not in listed]
        if extra:
            msg = (f"{len(extra)} image file(s) in {root} not listed in session.json, left "
                   "alone: " + ", ".join(extra[:10]) + (" ..." if len(extra) > 10 else ""))
            log.warning(msg)
            warnings.append(msg)
    else:
        unread = photos.list_unread(root)
        conv = (f"; {len(unread)} file(s) of a format not read ({unread[0]}"
                f"{', ...' if len(unread) > 1 else ''}): convert them to JPEG or PNG"
                if unread else "")
        if not present:
            raise VisionCalError("no photos: session.json has no images list and the folder "
                                 f"has no {'/'.join(s[1:] for s in photos.PHOTO_SUFFIXES)} "
                                 f"file{conv}", file=str(session.path), field="images")
        if unread:
            notes.append(conv[2:])
        items = [_Photo(f, None) for f in present]

    # checked in this process before anything is decoded or dispatched
    for ph in items:
        _check_photo(ph, root, session)
    if not session.images_listed:
        items = _capture_order(items, notes)
        warnings.extend(notes)
    first_of: dict[str, str] = {}
    for ph in items:
        if ph.det is None and ph.sha256 in first_of:
            ph.det = _skip(ph.file, f"repeated photo: the same file as {first_of[ph.sha256]}")
        elif ph.det is None:
            first_of[ph.sha256] = ph.file
    return items, warnings, notes


def detect_all(items: list[_Photo], session: Session, cache: DetectionCache, *,
               jobs: int | None = None, progress=None,
               config: EstimatorConfig | None = None) -> list[str]:
    """Stage 1 of every photo not skipped yet (``ph.det`` filled): from the cache, else in
    ``jobs`` worker processes (fewer when large photos would not fit
    :data:`MAX_PIXELS_IN_FLIGHT`), with a progress bar. Returns the warnings."""
    root = Path(session.root)
    warnings: list[str] = []
    config = config or DEFAULT
    fp = session_fingerprint(session, config)
    todo = []
    for i, ph in enumerate(items):
        if ph.det is not None:
            continue
        ph.key = cache_key(ph.sha256, fp)
        hit = cache.get(ph.key)
        if hit is not None:
            ph.det, ph.cached = replace(hit, file=ph.file), True
        else:
            todo.append(i)
    jobs = int(jobs or os.cpu_count() or 1)
    n_jobs = jobs_for(jobs, [items[i].pixels for i in todo])
    if n_jobs < jobs and len(todo) > 1:
        warnings.append(f"{n_jobs} worker(s) instead of {jobs}: photos of up to "
                        f"{max(items[i].pixels for i in todo) / 1e6:.0f} MP, at most "
                        f"{MAX_PIXELS_IN_FLIGHT / 1e6:.0f} MP are decoded at once")
    jobs = n_jobs
    # the photos found in the folder when session.json lists none: count what is measured
    n_cached = sum(bool(ph.cached) for ph in items)
    bar = progress_bar(progress, total=len(todo) if todo else n_cached,
                       desc=f"measure {root.name}", unit="photo",
                       note=(f"{min(jobs, max(len(todo), 1))} job(s)"
                             + (f", {n_cached} more from the cache" if n_cached else ""))
                       if todo else "all from the cache")
    if not todo and bar:
        bar.update(n_cached)
    args = [(root, items[i].file, session, items[i].sha256, config) for i in todo]
    try:
        if jobs <= 1 or len(todo) <= 1:
            results = (_worker(a) for a in args)
        else:
            ex = ProcessPoolExecutor(max_workers=min(jobs, len(todo)),
                                     initializer=_pool_initializer, initargs=(os.getpid(),))
            results = ex.map(_worker, args, chunksize=1)
        try:
            for i, d in zip(todo, results):
                items[i].det = d
                if d.reason is None or not d.reason.startswith("changed while"):
                    cache.put(items[i].key, d)
                if bar:
                    bar.update()
        finally:
            if jobs > 1 and len(todo) > 1:
                ex.shutdown(wait=True, cancel_futures=True)
    finally:
        if bar:
            bar.close()
    return warnings


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
    """Every photo's final mapping and dots (:func:`finish_image`); the sheet's declaration
    checked (markers that do not fit it stop the run, a misdeclared grid is dropped: the
    markers win), the photo before as the print under new marks (``listed_marks``: per
    photo the marks session.json lists, None when not listed;
    :mod:`vision_cal.measure.previous_photo`) and a photo moved as a whole against the
    others left out. Returns (images, warnings)."""
    warnings: list[str] = []
    images = [finish_image(d, session, lens, from_cache=c, config=config) for d, c in zip(dets, cached)]
    _check_sheet_fits(session, images)
    wrong_grid = misdeclared_grid(images, session.sheet.grid_spec, config.grid_declaration,
                                  height_config=config.sheet_height)
    if wrong_grid is not None:   # two references disagree by a constant: the markers win
        log.warning(wrong_grid.message)
        warnings.append(wrong_grid.message)
        session = replace(session, sheet=replace(session.sheet, grid=None))
        images = [finish_image(d, session, lens, from_cache=c, config=config)
                  for d, c in zip(dets, cached)]

    # the tests for ink under a mark against this series' plain ground, not the blank
    # paper's noise (JPEG, grid lines a few pixels apart, a low resolution)
    ok = [im for im in images if im.status == "ok"]
    g = ground_scale([x for im in ok for x in im.dots_bg_residual],
                     [b for im in ok for b in im.dots_background],
                     [u for im in ok for u in im.dots_printed_under], config.dots)
    if g > 1.0:
        images = [finish_image(d, session, lens, from_cache=c, ground_scale=g, config=config)
                  if any(im.dots_unreliable) else im
                  for d, c, im in zip(dets, cached, images)]

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
                                     previous=prev, ground_scale=g, config=config)

    # a photo moved as a whole against the others is left out, not the marks it shares
    for k, why in disagreeing_photos(images, config.photo_agreement).items():
        log.warning("%s: %s", images[k].file, why)
        warnings.append(f"{images[k].file}: {why}")
        images[k] = replace(images[k], status="skipped", reason=why)
    return images, warnings


@dataclass(frozen=True)
class AssociatedDots:
    """Stage 3's result: the dot groups across photos, which mark each group is
    (``assoc``: :class:`vision_cal.measure.associate` result), which marks each photo
    shows, and how they were inferred (None when session.json lists them)."""

    groups: list
    assoc: object
    image_marks: list
    inferred: object | None
    warnings: list

    def unassigned(self, files: list[str]) -> list[dict]:
        """The dot groups no mark took: mean position and the photos they are on."""
        used = set(self.assoc.mark_to_group.values())
        return [{"xy_mm": g.mean_mm.tolist(), "files": [files[k] for k in g.images]}
                for gi, g in enumerate(self.groups) if gi not in used]


def associate_dots(session: Session, items: list[_Photo], images: list[ImageResult],
                   ac: AssociationConfig, default_diameter_mm: float,
                   plan_match: PlanMatchConfig | None = None) -> AssociatedDots:
    """Stage 3: dots grouped across photos and the groups matched to the planned marks
    (which marks a photo shows: listed, or inferred); photos that do not match the plan
    stop the run (:mod:`vision_cal.measure.plan_match`). Each photo's ``dots_mark`` is set
    in ``images``."""
    warnings: list[str] = []
    files = [ph.file for ph in items]
    idx_ok = [i for i, r in enumerate(images) if r.status == "ok"]
    per_image = [(i, images[i].dots_xy_mm, images[i].dots_cov_mm2) for i in idx_ok]
    dia = session.pen_mark_diameter_mm or default_diameter_mm
    groups = assoc.group_dots(per_image, tol_mm=max(ac.group_tol_diameters * dia,
                                                    ac.group_tol_min_mm))
    mark_ids = [m.id for m in session.marks]
    if session.images_listed:
        image_marks = [tuple(ph.listed_marks) for ph in items]
        inferred = None
    else:
        inferred = infer_image_marks(len(items), idx_ok, groups, mark_ids, files, ac)
        image_marks = list(inferred.marks)
        warnings.extend(inferred.warnings)
        n_off = sum(1 for r in images if r.status != "ok")
        if n_off:
            warnings.append(f"{n_off} photo(s) in the folder not used (not of the sheet, "
                            "repeated or unreadable): see images[].reason")
    mark_images = [{i for i in idx_ok if m.id in image_marks[i]} for m in session.marks]
    q_assoc, assoc_model = session.joints_deg, session.robot.params
    with_tool = session.uses_joint4 and session.robot.tool_mm is not None   # #21
    if with_tool:
        q_assoc, assoc_model = _tool_joints(session.robot.params, session.robot.tool_mm,
                                            session)
    a = assoc.associate(q_assoc, mark_ids, mark_images, groups,
                        assoc_model, max_zero_deg=ac.max_zero_deg,
                        max_base_mm=ac.max_base_mm)
    if with_tool:
        a = _with_fitted_tool(a, session, mark_ids, mark_images, groups, ac)
    warnings.extend(a.warnings)
    check_plan_match(session.path, files, images, image_marks, len(groups), len(a.mark_to_group),
                     plan_match)
    dot_mark = [[""] * len(im.dots_xy_mm) for im in images]
    for mid, gi in a.mark_to_group.items():
        for k, j in zip(groups[gi].images, groups[gi].dot_index):
            dot_mark[k][j] = mid
    for k, im in enumerate(images):
        if im.status == "ok":
            images[k] = replace(im, dots_mark=tuple(dot_mark[k]))
    return AssociatedDots(groups, a, image_marks, inferred, warnings)


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
        g = dots.groups[gi]
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
        if marks[mid].status == "ok":
            g = _without_flagged(dots.groups[gi], images)
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
            mm = marks[mid]
            if mm.reference == "markers":
                continue
            g = _without_flagged(dots.groups[gi], images)
            gg = assoc.DotGroup(
                np.array([images[k].dots_global_xy_mm[j] for k, j in zip(g.images, g.dot_index)]),
                np.array([images[k].dots_global_cov_mm2[j]
                          for k, j in zip(g.images, g.dot_index)]), g.images, g.dot_index)
            xy, cov, spread = assoc.combine(gg,
                                            common_fraction=config.association.common_fraction)
            marks[mid] = replace(mm, xy_mm=xy, cov_mm2=cov, spread_mm=spread,
                                 reference="markers (sheet flat)")
    return heights, hmap, hnote
