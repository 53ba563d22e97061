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
   (``vision_cal.measure.associate``).

Nothing is ever written into the input folder: results and the cache go to ``out_dir``.
"""

from __future__ import annotations

import hashlib
import logging
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from datetime import datetime
from pathlib import Path

import cv2
import numpy as np

from vision_cal.config import DEFAULT, AssociationConfig
from vision_cal.dataset import photos
from vision_cal.dataset.io import atomic_write_json
from vision_cal.dataset.session import Session, load_session
from vision_cal.errors import VisionCalError
from vision_cal.measure import associate as assoc
from vision_cal.measure.aruco import (MIN_MARKERS, corners_from_edges, edge_points,
                                     find_sheet_markers)
from vision_cal.measure.cache import DetectionCache, cache_key, session_fingerprint
from vision_cal.measure.infer import infer_image_marks
from vision_cal.dataset.marker_geometry import marker_geometry
from vision_cal.measure.dots import DotCandidates, blank_regions, find_candidates, refine_dot
from vision_cal.measure.printed import printed_reference
from vision_cal.measure.rotated import to_main_px, transposed, turned_lens
from vision_cal.measure.sheetfit import (LENS_CAUSE, MISFIT, corner_tolerance_mm,
                                         misfit_reason)
from vision_cal.measure.mapping import (LensEstimate, distort_px, estimate_lens, fit_mapping,
                                       undistort_px)

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = set(photos.PHOTO_SUFFIXES)
BLANK_STD = 2.0


# --------------------------------------------------------------------------- results

@dataclass(frozen=True)
class ImageDetections:
    """Stage-1 result of one photo (cached): markers and dot candidates in raw pixels."""

    file: str
    status: str
    reason: str | None = None
    size_px: tuple[int, int] | None = None
    marker_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    corners_px: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 2)))
    corners_mm: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 2)))
    candidates: DotCandidates | None = None
    edges_px: np.ndarray | None = None  # (M, 4, n, 2) sub-pixel points on marker edges
    # with a declared sheet.grid: per candidate a wider uint16 patch of R+G+B around it (the
    # printed lines that are its local reference) and its top-left (col, row)
    grid_patches: tuple | None = None
    grid_origins: np.ndarray | None = None

    def corners_for(self, K=None, dist=None) -> np.ndarray:
        """Marker corners (M, 4, 2) in raw px: intersections of the border edges, fitted
        as straight lines in ideal pixels when a lens is given.

        Computed once per lens and kept with the detections (read-only: callers copy
        before changing it)."""
        if self.edges_px is None:
            return self.corners_px
        memo = self.__dict__.setdefault("_corners_memo", {})   # not a field: replace() drops it
        key = _lens_key(K, dist)
        if key not in memo:
            memo[key] = self._corners_for(K, dist)
        return memo[key]

    def _corners_for(self, K, dist) -> np.ndarray:
        if K is None:
            return corners_from_edges(self.edges_px, self.corners_px)
        e = undistort_px(self.edges_px.reshape(-1, 2), K, dist).reshape(self.edges_px.shape)
        c0 = undistort_px(self.corners_px.reshape(-1, 2), K, dist).reshape(-1, 4, 2)
        c = corners_from_edges(e, c0)
        return distort_px(c.reshape(-1, 2), K, dist).reshape(-1, 4, 2)

    def with_candidates(self, candidates: DotCandidates) -> "ImageDetections":
        """The same detections with dot candidates (the corners found so far kept)."""
        out = replace(self, candidates=candidates)
        out.__dict__["_corners_memo"] = self.__dict__.get("_corners_memo", {})
        return out

    def keep_markers(self, keep: np.ndarray) -> "ImageDetections":
        """The detections of the markers ``keep`` (bool (M,)), corners found so far kept
        (each marker's corners depend on its own edges only)."""
        out = replace(self, marker_ids=self.marker_ids[keep], corners_px=self.corners_px[keep],
                      corners_mm=self.corners_mm[keep],
                      edges_px=None if self.edges_px is None else self.edges_px[keep])
        memo = self.__dict__.get("_corners_memo", {})
        out.__dict__["_corners_memo"] = {k: c[keep] for k, c in memo.items()}
        return out


def _dot_field(im: "ImageResult", name: str, j: int) -> str:
    """Per-dot text field of a photo's result ("" when absent: older caches)."""
    v = getattr(im, name, ())
    return v[j] if j < len(v) else ""


def _lens_key(K, dist):
    if K is None:
        return None
    d = np.zeros(0) if dist is None else np.asarray(dist, float)
    return (np.asarray(K, float).tobytes(), d.tobytes())


@dataclass(frozen=True)
class ImageResult:
    """One photo measured. ``dots_xy_mm`` (K, 2), ``dots_cov_mm2`` (K, 2, 2), ``dots_uv_px``
    (K, 2); ``rejected``: reason -> count of blobs that were not taken as pen marks."""

    file: str
    status: str
    reason: str | None = None
    n_markers: int = 0
    corner_rms_px: float = float("nan")
    corner_rms_mm: float = float("nan")
    n_dots: int = 0
    dots_xy_mm: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    dots_cov_mm2: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))
    dots_uv_px: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    rejected: dict = field(default_factory=dict)
    noise_sigma: float = float("nan")
    size_px: tuple[int, int] | None = None
    from_cache: bool = False
    marker_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, int))   # (M,)
    markers_px: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 2)))  # (M, 4, 2)
    # added: the marker-mapping centre of each dot (K, 2), the printed-grid offset seen
    # around it (K, 2; NaN where the grid was not used) and which reference was used
    dots_global_xy_mm: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    dots_grid_offset_mm: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    dots_reference: tuple = ()
    dots_global_cov_mm2: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))
    dots_grid_offset_cov_mm2: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))
    mapping: object | None = field(default=None, repr=False, compare=False)
    K: np.ndarray | None = None     # the lens used for this photo's mapping (None: unknown)
    # added: per dot why its centre cannot be trusted ("" when it can) and what is printed
    # under it ("" for paper and grid lines; vision_cal.measure.printed)
    dots_unreliable: tuple = ()
    dots_printed_under: tuple = ()

    def to_json(self) -> dict:
        """The photo's entry of calibration.json ``images[]``."""
        d: dict = {"file": self.file, "status": self.status}
        if self.reason:
            d["reason"] = self.reason
        if self.status == "ok":
            d.update({"n_markers": self.n_markers,
                      "corner_rms_px": round(float(self.corner_rms_px), 4),
                      "corner_rms_mm": round(float(self.corner_rms_mm), 5),
                      "n_dots": self.n_dots})
            if self.rejected:
                d["rejected_blobs"] = dict(self.rejected)
        return d


@dataclass(frozen=True)
class MarkMeasurement:
    """A pen mark on the sheet: ``xy_mm`` (2,), ``cov_mm2`` (2, 2), seen in ``n_photos``
    photos whose estimates scatter by ``spread_mm`` (RMS about the mean)."""

    xy_mm: np.ndarray
    cov_mm2: np.ndarray
    n_photos: int
    spread_mm: float
    how: str = "model"
    files: tuple[str, ...] = ()
    reference: str = "markers"          # grid | markers | mixed: what the photos measured against
    local_minus_global_mm: np.ndarray | None = None   # mean over photos of (grid - markers)
    local_minus_global_std_mm: np.ndarray | None = None
    #: "ok", or "unreliable" with ``reason``: every photo's dot of it could not be separated
    #: from what is printed under it (docs/format.md: left out of the fit)
    status: str = "ok"
    reason: str = ""
    printed_under: str = ""

    @property
    def std_mm(self) -> np.ndarray:
        return np.sqrt(np.diag(self.cov_mm2))


@dataclass(frozen=True)
class Measurement:
    marks: dict
    images: list
    lens: LensEstimate | None = None
    unassigned: list = field(default_factory=list)
    refused: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    #: per photo (``images`` order) the marks on the sheet: listed, or inferred
    image_marks: tuple = ()
    #: how they were inferred ("series" | "finished" | "none"), None when listed
    inferred: str | None = None
    #: what the inference found odd (a repeated or missing photo, extra dots), one line each
    inferred_notes: tuple = ()

    def session_images(self) -> list[dict]:
        """``images`` for session.json: every usable photo and the marks it shows."""
        return [{"file": im.file, "marks": list(ms)}
                for im, ms in zip(self.images, self.image_marks) if im.status == "ok"]
    heights: dict = field(default_factory=dict)     # id -> measure.height.MarkHeight
    height_map: object | None = None                # measure.height.HeightMap
    height_note: str | None = None

    def images_json(self) -> list[dict]:
        return [im.to_json() for im in self.images]

    def effects_json(self) -> list[dict]:
        out = [self.lens.to_effect_json()] if self.lens is not None and self.lens.kept else []
        if self.height_map is not None and self.height_map.claimed:
            out.append(self.height_map.to_effect_json())
        return out

    def mark_json(self, mid: str) -> dict:
        """Added per-mark fields: reference, local-minus-global difference, height."""
        d = mark_reference_json(self.marks[mid])
        if mid in self.heights:
            d.update(self.heights[mid].to_json())
        return d

    def to_json(self) -> dict:
        return {"marks": {k: {"measured_mm": m.xy_mm.tolist(), "cov_mm2": m.cov_mm2.tolist(),
                              "n_photos": m.n_photos, "spread_mm": m.spread_mm, "how": m.how,
                              **self.mark_json(k)}
                          for k, m in self.marks.items()},
                "images": self.images_json(), "effects": self.effects_json(),
                "lens": None if self.lens is None else {
                    **self.lens.to_effect_json(), "kept": self.lens.kept,
                    "candidates_heldout_rms_px": self.lens.candidates},
                "unassigned": self.unassigned, "refused": self.refused,
                "warnings": self.warnings, "inferred": self.inferred,
                "inferred_notes": list(self.inferred_notes),
                "image_marks": [list(m) for m in self.image_marks],
                "sheet_height": (self.height_map.to_json() if self.height_map is not None
                                 else {"claimed": False, "note": self.height_note})}


def mark_reference_json(m: "MarkMeasurement") -> dict:
    """Added mark fields: the reference used and the local-versus-global difference (and
    the contract's ``status`` / ``reason`` of a mark that cannot be trusted, what is printed
    under it)."""
    d = {"reference": m.reference}
    if m.status != "ok":
        d.update(status=m.status, reason=m.reason)
    if m.printed_under:
        d["printed_under"] = m.printed_under
    if m.local_minus_global_mm is not None:
        d["local_minus_global_mm"] = [float(v) for v in m.local_minus_global_mm]
        d["local_minus_global_std_mm"] = [float(v) for v in m.local_minus_global_std_mm]
    return d


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


def _drop_deformed_markers(d: ImageDetections, K, dist, *, min_px: float = 0.5,
                           factor: float = 5.0):
    """Leave out markers whose corners do not fit the sheet's shape (a corner on the arm's
    edge, a marker half hidden): residuals of a homography fitted to all markers, with each
    marker's mean residual removed (so that an undeclared lens, smooth over a marker, does
    not count), above ``max(min_px, factor x median)``. Returns (detections, n dropped)."""
    n_drop = 0
    for _ in range(3):
        M = len(d.marker_ids)
        if M < MIN_MARKERS + 1:
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


def detect_image_bytes(data: bytes, file: str, session: Session) -> ImageDetections:
    """Stage 1 on one photo's bytes (pure function of its inputs)."""
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
    if float(gray[::4, ::4].std()) < BLANK_STD:
        return _skip(file, "blank image: no contrast", size)
    det = find_sheet_markers(gray, session.sheet)
    if det.reason:
        return ImageDetections(file, "skipped", det.reason, size, det.ids, det.corners_px,
                               det.corners_mm)
    K = None if cam is None else cam.K
    dist = None if cam is None else cam.dist
    out = ImageDetections(file, "ok", None, size, det.ids, det.corners_px, det.corners_mm,
                          None, edge_points(gray, det.corners_px,
                                            geometry=marker_geometry(session.sheet)))
    out, n_bad = _drop_deformed_markers(out, K, dist)
    if len(out.marker_ids) < MIN_MARKERS:
        return _skip(file, f"too few markers: {len(out.marker_ids)} usable after {n_bad} "
                           "deformed ones (partly hidden?) were left out", size)
    try:
        approx = fit_mapping(out.corners_mm.reshape(-1, 2),
                             out.corners_for(K, dist).reshape(-1, 2), K=K, dist=dist)
    except VisionCalError as e:
        return _skip(file, f"no mapping: {e.reason}", size)
    cand = find_candidates(rgb, approx, session.sheet, dia_mm=session.pen_mark_diameter_mm)
    gp, go = None, None
    if session.sheet.grid_spec is not None and len(cand.uv_px):
        gp, go = _grid_patches(rgb, approx, cand.uv_px)
    out = out.with_candidates(cand)
    if gp is None:
        return out
    out2 = replace(out, grid_patches=gp, grid_origins=go)
    out2.__dict__["_corners_memo"] = out.__dict__.get("_corners_memo", {})
    return out2


def _grid_patches(rgb, mapping, uv_px):
    """uint16 R+G+B patches around each candidate wide enough for the local grid window."""
    from vision_cal.measure.grid import GRID_HALF_MM

    H, W = rgb.shape[:2]
    xy = mapping.image_to_sheet(uv_px)
    mmpp = mapping.mm_per_px(xy)
    patches, origins = [], []
    for (u, v), mpp in zip(uv_px, mmpp):
        hp = int(np.ceil(1.2 * (GRID_HALF_MM + 0.5) / max(float(mpp), 1e-6))) + 2
        cu, cv_ = int(round(u)), int(round(v))
        c0, r0 = max(cu - hp, 0), max(cv_ - hp, 0)
        c1, r1 = min(cu + hp + 1, W), min(cv_ + hp + 1, H)
        patches.append(rgb[r0:r1, c0:c1].astype(np.uint16).sum(axis=2, dtype=np.uint16))
        origins.append((c0, r0))
    return tuple(patches), np.asarray(origins, int).reshape(-1, 2)


def detect_image(path, session: Session, *, root=None, name: str | None = None,
                 sha256: str | None = None) -> ImageDetections:
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
    return detect_image_bytes(data, name, session)


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
                 *, from_cache: bool = False) -> ImageResult:
    """Stage 2: final mapping and dot centres on the sheet."""
    if det.status != "ok":
        return ImageResult(det.file, det.status, det.reason, n_markers=len(det.marker_ids),
                           size_px=det.size_px, from_cache=from_cache)
    K, dist = _lens_of(session, lens, det.size_px)
    corners_px = det.corners_for(K, dist)
    m = fit_mapping(det.corners_mm.reshape(-1, 2), corners_px.reshape(-1, 2), K=K, dist=dist)
    tol = corner_tolerance_mm(det.corners_mm,
                              float(np.median(m.mm_per_px(det.corners_mm.mean(axis=1)))))
    if not m.corner_rms_mm <= tol:  # the markers do not fit the declared sheet
        return ImageResult(det.file, "skipped",
                           misfit_reason(det.corners_mm, corners_px, m.corner_rms_mm, tol,
                                         raw_px=(det.corners_for(None, None)
                                                 if dist is not None and np.any(dist) else None)),
                           n_markers=len(det.marker_ids), corner_rms_px=m.corner_rms_px,
                           corner_rms_mm=m.corner_rms_mm, size_px=det.size_px,
                           from_cache=from_cache)
    c = det.candidates
    dia = session.pen_mark_diameter_mm
    xy0 = m.image_to_sheet(c.uv_px) if len(c.uv_px) else np.zeros((0, 2))
    xs, covs, uvs, xg, offs, refs, gcov, ocov = [], [], [], [], [], [], [], []
    unrel, under = [], []
    rejected = dict(c.rejected)
    blank = blank_regions(session.sheet)
    grid = session.sheet.grid_spec
    have_grid = grid is not None and det.grid_patches is not None
    pref = printed_reference(session.sheet)
    # the local grid reference leaves out what is printed over or instead of the grid
    grid_blank = blank if pref is None else np.concatenate([blank, pref.ungridded_boxes_mm()])
    for k, (patch, org, x0, uv) in enumerate(zip(c.patches, c.origins, xy0, c.uv_px)):
        r = refine_dot(patch, org, m, x0, dia_mm=dia, noise_sigma=c.noise_sigma,
                       blank_rects=blank, printed=pref)
        if r is None:
            rejected["not measurable"] = rejected.get("not measurable", 0) + 1
            continue
        xy, cov, off, ref = r.xy_mm, r.cov_mm2, np.full(2, np.nan), "markers"
        oc = np.full((2, 2), np.nan)
        if have_grid and not r.printed_under:   # over print, the grid around is interrupted
            go = _local_grid(det, k, m, r.xy_mm, grid, dia, grid_blank)
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
    return ImageResult(det.file, "ok", None, len(det.marker_ids), m.corner_rms_px,
                       m.corner_rms_mm, len(xs), np.asarray(xs).reshape(-1, 2),
                       np.asarray(covs).reshape(-1, 2, 2), np.asarray(uvs).reshape(-1, 2),
                       rejected, c.noise_sigma, det.size_px, from_cache,
                       np.asarray(det.marker_ids), det.corners_for(K, dist),
                       np.asarray(xg).reshape(-1, 2), np.asarray(offs).reshape(-1, 2),
                       tuple(refs), np.asarray(gcov).reshape(-1, 2, 2),
                       np.asarray(ocov).reshape(-1, 2, 2), m, K, tuple(unrel), tuple(under))


def _local_grid(det: ImageDetections, k: int, mapping, xy_mm, grid, dia, blank):
    """The printed grid's offset around candidate ``k`` (None: not usable)."""
    from vision_cal.measure.dots import DEFAULT_DIAMETER_MM, _radii_mm
    from vision_cal.measure.grid import grid_offset

    if k >= len(det.grid_patches):
        return None
    r_win, _ = _radii_mm(float(dia or DEFAULT_DIAMETER_MM), float(mapping.mm_per_px(xy_mm)[0]))
    return grid_offset(det.grid_patches[k], det.grid_origins[k], mapping, xy_mm, grid,
                       exclude_r_mm=r_win, blank_rects=blank)


def measure_image(path, session: Session, *, lens: LensEstimate | None = None) -> ImageResult:
    """Measure one photo (markers, mapping, dots in sheet mm). Pure; the result pickles."""
    return finish_image(detect_image(path, session), session, lens)


# --------------------------------------------------------------------------- batch

def _worker(args):
    root, name, session, sha = args
    return detect_image(Path(root) / name, session, root=root, name=name, sha256=sha)


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
    from vision_cal.measure.workers import exit_with_parent

    exit_with_parent(parent_pid)


def measure_folder(session, *, out_dir, jobs: int | None = None, cache_dir=None,
                   progress=None, association: AssociationConfig | None = None) -> Measurement:
    """Measure every photo of a dataset folder and every pen mark on the sheet.

    ``session``: a :class:`Session` or a folder. ``out_dir``: where results go (never the
    input folder); the cache defaults to ``out_dir/.cache``. ``jobs``: worker processes
    (default ``os.cpu_count()``; 1 runs in this process). ``progress``: a tqdm bar on stderr.
    ``association``: grouping and matching thresholds (default ``vision_cal.config``).
    Without ``images`` in session.json every photo in the folder is measured and which
    marks each shows is inferred (:mod:`vision_cal.measure.infer`).
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
    warnings: list[str] = []
    notes: list[str] = []  # no images list: what the user should see on the console

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
    files = [ph.file for ph in items]

    # stage 1, cached
    fp = session_fingerprint(session)
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
    from vision_cal.progress import bar as progress_bar

    # the photos found in the folder when session.json lists none: count what is measured
    n_cached = sum(bool(ph.cached) for ph in items)
    bar = progress_bar(progress, total=len(todo) if todo else n_cached,
                       desc=f"measure {root.name}", unit="photo",
                       note=(f"{min(jobs, max(len(todo), 1))} job(s)"
                             + (f", {n_cached} more from the cache" if n_cached else ""))
                       if todo else "all from the cache")
    if not todo and bar:
        bar.update(n_cached)
    args = [(root, items[i].file, session, items[i].sha256) for i in todo]
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
    dets = [ph.det for ph in items]
    cached = [ph.cached for ph in items]

    # stage 2: the lens
    lens = None
    if session.camera is None:
        ok = [d for d in dets if d.status == "ok"]
        sizes = sorted({d.size_px for d in ok}, key=lambda s: -sum(x.size_px == s for x in ok))
        if sizes:
            size = sizes[0]
            views = [(d.marker_ids, d.corners_mm, d.corners_for()) for d in ok
                     if d.size_px == size]
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
            if rest:
                warnings.append(f"photos of {len(rest) + 1} image sizes: a lens is estimated "
                                f"only for {size[0]}x{size[1]} px"
                                + (" (and the same camera turned)" if turned else ""))
    images = [finish_image(d, session, lens, from_cache=c) for d, c in zip(dets, cached)]
    _check_sheet_fits(session, images)
    from vision_cal.measure.grid_declaration import misdeclared_grid

    wrong_grid = misdeclared_grid(images, session.sheet.grid_spec)
    if wrong_grid is not None:   # two references disagree by a constant: the markers win
        log.warning(wrong_grid.message)
        warnings.append(wrong_grid.message)
        session = replace(session, sheet=replace(session.sheet, grid=None))
        images = [finish_image(d, session, lens, from_cache=c) for d, c in zip(dets, cached)]

    # a photo moved as a whole against the others is left out, not the marks it shares
    from vision_cal.measure.photo_agreement import disagreeing_photos

    for k, why in disagreeing_photos(images).items():
        log.warning("%s: %s", images[k].file, why)
        warnings.append(f"{images[k].file}: {why}")
        images[k] = replace(images[k], status="skipped", reason=why)
    # stage 3: association
    idx_ok = [i for i, r in enumerate(images) if r.status == "ok"]
    per_image = [(i, images[i].dots_xy_mm, images[i].dots_cov_mm2) for i in idx_ok]
    ac = association or DEFAULT.association
    dia = session.pen_mark_diameter_mm or DEFAULT.dots.default_diameter_mm
    groups = assoc.group_dots(per_image, tol_mm=max(ac.group_tol_diameters * dia,
                                                    ac.group_tol_min_mm))
    mark_ids = [m.id for m in session.marks]
    if session.images_listed:
        image_marks = [tuple(ph.listed_marks) for ph in items]
        inferred = None
    else:
        inferred = infer_image_marks(len(items), idx_ok, groups, mark_ids, files)
        image_marks = list(inferred.marks)
        warnings.extend(inferred.warnings)
        n_off = sum(1 for r in images if r.status != "ok")
        if n_off:
            warnings.append(f"{n_off} photo(s) in the folder not used (not of the sheet, "
                            "repeated or unreadable): see images[].reason")
    mark_images = [{i for i in idx_ok if m.id in image_marks[i]} for m in session.marks]
    q_assoc = session.joints_deg
    if session.uses_joint4 and session.robot.tool_mm is not None:   # an off-axis tool (#21)
        from vision_cal.plan.orient import equivalent_joints

        eq = equivalent_joints(session.robot.params, session.robot.tool_mm, q_assoc,
                               session.j4_deg)
        q_assoc = np.where(np.isfinite(eq), eq, q_assoc)
    a = assoc.associate(q_assoc, mark_ids, mark_images, groups,
                        session.robot.params, max_zero_deg=ac.max_zero_deg,
                        max_base_mm=ac.max_base_mm)
    warnings.extend(a.warnings)
    from vision_cal.measure.plan_match import check_plan_match

    check_plan_match(session.path, files, images, image_marks, len(groups), len(a.mark_to_group))
    marks = {}
    used = set()
    for mid, gi in a.mark_to_group.items():
        g = groups[gi]
        used.add(gi)
        why = [_dot_field(images[k], "dots_unreliable", j) for k, j in zip(g.images, g.dot_index)]
        status, reason = "ok", ""
        if all(why):
            status, reason = "unreliable", why[0]
        elif any(why):   # measured without the photos whose dot could not be separated
            keep = [i for i, w in enumerate(why) if not w]
            g = assoc.DotGroup(g.xy_mm[keep], g.cov_mm2[keep],
                               tuple(g.images[i] for i in keep),
                               tuple(g.dot_index[i] for i in keep))
        under = next((u for u in (_dot_field(images[k], "dots_printed_under", j)
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
        marks[mid] = MarkMeasurement(xy, cov, len(g.images), spread, a.how.get(mid, "model"),
                                     tuple(files[k] for k in g.images), ref,
                                     lmg, lmg_sd, status, reason, under)
    unassigned = [{"xy_mm": g.mean_mm.tolist(),
                   "files": [files[k] for k in g.images]}
                  for gi, g in enumerate(groups) if gi not in used]
    refused = {k: v for k, v in a.refused.items()}
    # stage 4: the sheet's height (parallax against the grid or between camera places)
    from vision_cal.measure.height import sheet_heights

    groups_of = {mid: list(zip(groups[gi].images, groups[gi].dot_index))
                 for mid, gi in a.mark_to_group.items()}
    heights, hmap, hnote = {}, None, None
    try:
        heights, hmap, hnote = sheet_heights(images, marks, groups_of, session.sheet.extent_mm,
                                             K_fallback=None if lens is None else lens.K)
    except (VisionCalError, np.linalg.LinAlgError) as e:
        hnote = f"no height map: {e}"
    if hmap is not None and hmap.claimed:
        # the paper is not flat: marks seen only through the marker mapping take the paper
        # position that parallax between camera places found
        for mid, h in heights.items():
            mm = marks[mid]
            if mm.reference == "markers" and h.xy_mm is not None:
                marks[mid] = replace(mm, xy_mm=h.xy_mm, cov_mm2=h.cov_xy_mm2,
                                     reference="parallax")
    elif heights:
        # flat within what the grid and the views can see: the marker mapping is then the
        # better reference (the line phase adds its own few micrometres); the grid's
        # difference stays reported
        for mid, gi in a.mark_to_group.items():
            mm, g = marks[mid], groups[gi]
            if mm.reference == "markers":
                continue
            keep = [i for i, (k, j) in enumerate(zip(g.images, g.dot_index))
                    if not _dot_field(images[k], "dots_unreliable", j)]
            if keep and len(keep) < len(g.images):   # as above: without the flagged dots
                g = assoc.DotGroup(g.xy_mm[keep], g.cov_mm2[keep],
                                   tuple(g.images[i] for i in keep),
                                   tuple(g.dot_index[i] for i in keep))
            gg = assoc.DotGroup(
                np.array([images[k].dots_global_xy_mm[j] for k, j in zip(g.images, g.dot_index)]),
                np.array([images[k].dots_global_cov_mm2[j]
                          for k, j in zip(g.images, g.dot_index)]), g.images, g.dot_index)
            xy, cov, spread = assoc.combine(gg, common_fraction=ac.common_fraction)
            marks[mid] = replace(mm, xy_mm=xy, cov_mm2=cov, spread_mm=spread,
                                 reference="markers (sheet flat)")
    for r in images:
        if r.status != "ok":
            log.info("skipped %s: %s", r.file, r.reason)
    meas = Measurement(marks, images, lens, unassigned, refused, warnings,
                       tuple(image_marks), None if inferred is None else inferred.mode,
                       () if inferred is None else (*notes, *inferred.warnings),
                       heights, hmap, hnote)
    atomic_write_json(out_dir / "measurement.json", meas.to_json())
    return meas
