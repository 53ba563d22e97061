"""Stage 1, per photo, in parallel and cached by content (:func:`detect_image`): decode, find
the sheet's ArUco markers, an approximate homography, ink-dot candidates with small raw
patches (:mod:`vision_cal.measure.dots`). A bad photo is *skipped* with a one-line reason;
the batch goes on (:func:`detect_all`)."""

from __future__ import annotations

import hashlib
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.dataset import photos
from vision_cal.dataset.marker_geometry import marker_geometry
from vision_cal.dataset.session import Session
from vision_cal.errors import VisionCalError
from vision_cal.measure.aruco import edge_points, find_sheet_markers
from vision_cal.measure.cache import DetectionCache, cache_key, session_fingerprint
from vision_cal.measure.dots import find_candidates
from vision_cal.measure.listing import Photo, refusal, skipped
from vision_cal.measure.mapping import fit_mapping, undistort_px
from vision_cal.measure.types import ImageDetections
from vision_cal.measure.workers import exit_with_parent
from vision_cal.progress import bar as progress_bar


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
        return None, refusal(file, e)
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
                       config: EstimatorConfig | None = None, dots: bool = True
                       ) -> ImageDetections:
    """Stage 1 on one photo's bytes (pure function of its inputs; ``config``: the
    ``markers`` and ``dots`` thresholds, default ``vision_cal.config.DEFAULT``). ``dots``
    False: the markers and the mapping only, no pen marks looked for (a survey's photos
    of the blank sheet)."""
    config = config or DEFAULT
    cam = session.camera
    rgb, why = _decode(data, file, None if cam is None else cam.size_px)
    if rgb is None:
        return skipped(file, why)
    h, w = rgb.shape[:2]
    size = (int(w), int(h))
    if cam is not None and tuple(cam.size_px) != size:
        return skipped(file, f"wrong size: {w}x{h} px, camera.size_px says "
                           f"{cam.size_px[0]}x{cam.size_px[1]}", size)
    gray = cv2.cvtColor(rgb, cv2.COLOR_BGR2GRAY)
    if float(gray[::4, ::4].std()) < config.markers.blank_photo_std:
        return skipped(file, "blank image: no contrast", size)
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
        return skipped(file, f"too few markers: {len(out.marker_ids)} usable after {n_bad} "
                           "deformed ones (partly hidden?) were left out", size)
    try:
        approx = fit_mapping(out.corners_mm.reshape(-1, 2),
                             out.corners_for(K, dist).reshape(-1, 2), K=K, dist=dist)
    except VisionCalError as e:
        return skipped(file, f"no mapping: {e.reason}", size)
    if not dots:
        return out
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
        patches.append(photos.channel_sum(rgb[r0:r1, c0:c1], np.uint16))
        origins.append((c0, r0))
    return tuple(patches), np.asarray(origins, int).reshape(-1, 2)


def detect_image(path, session: Session, *, root=None, name: str | None = None,
                 sha256: str | None = None, identity: tuple | None = None,
                 config: EstimatorConfig | None = None, dots: bool = True) -> ImageDetections:
    """Stage 1 on one photo file: ``root``/``name`` (``name`` the photo's relative path,
    kept in the result), or ``path`` itself. ``sha256``: the content the caller checked
    (header, cache key); a file that changed since is skipped. ``identity``: the file's
    identity when the caller hashed it (:func:`photos.read_photo_identity`): read back
    unchanged, the bytes are the ones hashed (any write changes the file's change time)
    and are not hashed again; otherwise they are. ``dots``: as
    :func:`detect_image_bytes`."""
    path = Path(path)
    root = Path(root) if root is not None else path.parent
    name = name if name is not None else path.name
    try:
        data, now = photos.read_photo_identity(root, name)
    except photos.PhotoRefused as e:
        return skipped(name, e.reason)
    if sha256 is not None and (identity is None or tuple(now) != tuple(identity)) \
            and hashlib.sha256(data).hexdigest() != sha256:
        return skipped(name, "changed while being measured: run again")
    return detect_image_bytes(data, name, session, config=config, dots=dots)


def _worker(args):
    root, name, session, sha, identity, config, dots = args
    return detect_image(Path(root) / name, session, root=root, name=name, sha256=sha,
                        identity=identity, config=config, dots=dots)


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


def detect_all(items: list[Photo], session: Session, cache: DetectionCache, *,
               jobs: int | None = None, progress=None,
               config: EstimatorConfig | None = None, dots: bool = True) -> list[str]:
    """Stage 1 of every photo not skipped yet (``ph.det`` filled).

        items, warnings, notes = photos_to_measure(session)
        warnings += detect_all(items, session, DetectionCache("out/.cache"), jobs=4)

    From the cache, else in
    ``jobs`` worker processes (fewer when large photos would not fit
    :data:`MAX_PIXELS_IN_FLIGHT`), with a progress bar. ``dots`` False: the markers only
    (the arm camera's photos of the marker field), cached apart. Returns the warnings."""
    root = Path(session.root)
    warnings: list[str] = []
    config = config or DEFAULT
    fp = session_fingerprint(session, config, dots=dots)
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
                       if todo else "all from the cache" if n_cached else
                       "none to measure: every photo refused before")
    if not todo and bar:
        bar.update(n_cached)
    args = [(root, items[i].file, session, items[i].sha256, items[i].identity, config, dots)
            for i in todo]
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
