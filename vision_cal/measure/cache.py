"""Content-addressed cache of per-photo detections, data only.

Key = SHA-256 of (measuring-code version, the session parts that change a detection:
sheet, pen diameter, declared camera) and the SHA-256 of the photo's bytes.

An entry is an ``.npz`` of plain numeric arrays plus one JSON string (no pickle anywhere:
read with ``numpy.load(allow_pickle=False)``, which refuses object arrays), written
through a temporary file and a rename, so an interrupted run never leaves a torn entry.
Reading never runs code and trusts nothing: the entry must carry its own key and code
version, its members must be the expected numeric arrays with consistent shapes and its
uncompressed size bounded (:data:`MAX_ENTRY_BYTES`, so a planted zip bomb is not
inflated); anything else (a planted pickle, a corrupt or truncated file, an entry of
another version) is ignored and the photo measured again. Opening the cache removes
temporary files older than :data:`STALE_TMP_S` (left by a killed run) and entries of the
old pickle format, which are never read.
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import time
import zipfile
from dataclasses import asdict
from pathlib import Path

import numpy as np

from vision_cal.config import DEFAULT
from vision_cal.dataset.io import atomic_write_bytes
from vision_cal.measure.dots import DotCandidates
from vision_cal.measure.types import ImageDetections

log = logging.getLogger(__name__)

#: bump when anything that changes a detection changes
CODE_VERSION = "measure-6"  # 6: markers looked for with the layout before a refusal
#: largest entry read (uncompressed bytes of all members)
MAX_ENTRY_BYTES = 256 * 1024 * 1024
#: a temporary file older than this is left over from a killed run
STALE_TMP_S = 3600.0


def session_fingerprint(session, config=None, *, dots: bool = True) -> str:
    """What stage 1 depends on besides the photo: the sheet, pen, camera, the
    ``markers``/``dots``/``grid`` thresholds of ``config`` (an ``EstimatorConfig``) and
    whether the dots were looked for (``dots`` False: the markers only)."""
    cam = session.camera
    parts = {"sheet": session.sheet.to_json() if session.sheet else None,
             "pen": session.pen_mark_diameter_mm,
             "camera": None if cam is None else {"size": list(cam.size_px),
                                                 "K": np.asarray(cam.K).tolist(),
                                                 "dist": np.asarray(cam.dist).tolist()}}
    if config is not None and (config.markers, config.dots, config.grid) != (
            DEFAULT.markers, DEFAULT.dots, DEFAULT.grid):
        # stage 1's thresholds, when not the defaults (default runs keep their old keys)
        parts["config"] = {"markers": asdict(config.markers), "dots": asdict(config.dots),
                           "grid": asdict(config.grid)}
    if not dots:   # the markers only (a pen session's keys stay as they were)
        parts["markers_only"] = True
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def cache_key(photo_sha256: str, fingerprint: str) -> str:
    """``photo_sha256``: hex SHA-256 of the photo's bytes."""
    h = hashlib.sha256()
    h.update(CODE_VERSION.encode())
    h.update(fingerprint.encode())
    h.update(bytes.fromhex(photo_sha256))
    return h.hexdigest()


# --------------------------------------------------------------------------- encoding

_F = np.float64


def encode_detections(det, key: str) -> bytes:
    """An ImageDetections as npz bytes (numeric arrays and one JSON string)."""
    c = det.candidates
    meta = {"key": key, "version": CODE_VERSION, "file": det.file, "status": det.status,
            "reason": det.reason, "size_px": None if det.size_px is None else list(det.size_px),
            "has_edges": det.edges_px is not None, "has_candidates": c is not None}
    arrays = {"marker_ids": np.asarray(det.marker_ids, np.int64).reshape(-1),
              "corners_px": np.asarray(det.corners_px, _F).reshape(-1, 4, 2),
              "corners_mm": np.asarray(det.corners_mm, _F).reshape(-1, 4, 2)}
    if det.edges_px is not None:
        arrays["edges_px"] = np.asarray(det.edges_px, _F)
    if c is not None:
        meta.update(noise_sigma=float(c.noise_sigma), rejected=dict(c.rejected))
        shapes = np.array([p.shape for p in c.patches], np.int64).reshape(-1, 3)
        arrays.update(
            uv_px=np.asarray(c.uv_px, _F).reshape(-1, 2),
            origins=np.asarray(c.origins, np.int64).reshape(-1, 2),
            area_px=np.asarray(c.area_px, _F).reshape(-1),
            rejected_uv=np.asarray(c.rejected_uv, _F).reshape(-1, 2),
            patch_shapes=shapes,
            patches=(np.concatenate([np.asarray(p, np.uint8).ravel() for p in c.patches])
                     if len(c.patches) else np.zeros(0, np.uint8)))
    gp = getattr(det, "grid_patches", None)
    if gp is not None:  # the wider uint16 patches of the local grid reference
        meta["has_grid_patches"] = True
        arrays.update(
            grid_shapes=np.array([p.shape for p in gp], np.int64).reshape(-1, 2),
            grid_origins=np.asarray(det.grid_origins, np.int64).reshape(-1, 2),
            grid_patches=(np.concatenate([np.asarray(p, np.uint16).ravel() for p in gp])
                          if len(gp) else np.zeros(0, np.uint16)))
    arrays["meta"] = np.array(json.dumps(meta))
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


class _Bad(Exception):
    pass


def _arr(z, name, dtype_kind, shape_tail=None):
    if name not in z.files:
        raise _Bad(f"no {name}")
    a = z[name]
    if a.dtype.kind not in dtype_kind:
        raise _Bad(f"{name}: dtype {a.dtype}")
    if shape_tail is not None and (a.ndim != 1 + len(shape_tail) or a.shape[1:] != shape_tail):
        raise _Bad(f"{name}: shape {a.shape}")
    return a


def decode_detections(data: bytes, key: str):
    """The ImageDetections of an entry, or raise ``_Bad`` (never runs code)."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            if sum(i.file_size for i in zf.infolist()) > MAX_ENTRY_BYTES:
                raise _Bad("too large")
    except zipfile.BadZipFile as e:
        raise _Bad("not an npz") from e
    with np.load(io.BytesIO(data), allow_pickle=False) as z:
        meta_a = _arr(z, "meta", "U")
        meta = json.loads(str(meta_a.reshape(())))
        if not isinstance(meta, dict) or meta.get("key") != key or \
                meta.get("version") != CODE_VERSION:
            raise _Bad("another key or version")
        ids = _arr(z, "marker_ids", "iu")
        M = len(ids)
        cpx = _arr(z, "corners_px", "f", (4, 2))
        cmm = _arr(z, "corners_mm", "f", (4, 2))
        if len(cpx) != M or len(cmm) != M:
            raise _Bad("marker counts differ")
        edges = _arr(z, "edges_px", "f") if meta.get("has_edges") else None
        if edges is not None and (edges.ndim != 4 or edges.shape[:2] != (M, 4)
                                  or edges.shape[3] != 2):
            raise _Bad("edges shape")
        cand = None
        if meta.get("has_candidates"):
            uv = _arr(z, "uv_px", "f", (2,))
            K = len(uv)
            org = _arr(z, "origins", "i", (2,))
            area = _arr(z, "area_px", "f", ())
            shapes = _arr(z, "patch_shapes", "i", (3,))
            flat = _arr(z, "patches", "u")
            rej_uv = _arr(z, "rejected_uv", "f", (2,))
            if len(org) != K or len(area) != K or len(shapes) != K or (shapes < 0).any():
                raise _Bad("candidate counts differ")
            sizes = np.prod(shapes, axis=1)
            if int(sizes.sum()) != flat.size or flat.dtype != np.uint8:
                raise _Bad("patch sizes")
            ends = np.cumsum(sizes)
            patches = tuple(flat[e - n:e].reshape(s) for e, n, s in zip(ends, sizes, shapes))
            rejected = meta.get("rejected", {})
            if not isinstance(rejected, dict) or not all(
                    isinstance(v, int) for v in rejected.values()):
                raise _Bad("rejected")
            noise = meta.get("noise_sigma")
            if not isinstance(noise, (int, float)):
                raise _Bad("noise_sigma")
            cand = DotCandidates(uv, patches, org, area, float(noise), rejected, rej_uv)
        size = meta.get("size_px")
        if size is not None:
            if not (isinstance(size, list) and len(size) == 2
                    and all(isinstance(v, int) for v in size)):
                raise _Bad("size_px")
            size = (int(size[0]), int(size[1]))
        status, reason, file = meta.get("status"), meta.get("reason"), meta.get("file")
        if status not in ("ok", "skipped") or not isinstance(file, str) or \
                not (reason is None or isinstance(reason, str)):
            raise _Bad("status")
        gpatches = gorg = None
        if meta.get("has_grid_patches"):
            gsh = _arr(z, "grid_shapes", "i", (2,))
            gorg = _arr(z, "grid_origins", "i", (2,))
            gflat = _arr(z, "grid_patches", "u")
            if len(gorg) != len(gsh) or (gsh < 0).any() or gflat.dtype != np.uint16:
                raise _Bad("grid patch counts")
            gsz = np.prod(gsh, axis=1)
            if int(gsz.sum()) != gflat.size:
                raise _Bad("grid patch sizes")
            gend = np.cumsum(gsz)
            gpatches = tuple(gflat[e - n:e].reshape(s) for e, n, s in zip(gend, gsz, gsh))
        return ImageDetections(file, status, reason, size, ids.astype(int), cpx, cmm, cand,
                               edges, gpatches, gorg)


class DetectionCache:
    def __init__(self, folder):
        self.folder = Path(folder)
        self.clean()

    def _path(self, key: str) -> Path:
        return self.folder / key[:2] / f"{key}.npz"

    def clean(self, *, now: float | None = None) -> int:
        """Remove temporary files of killed runs and old-format entries; how many."""
        now = time.time() if now is None else now
        n = 0
        if not self.folder.is_dir():
            return 0
        for p in self.folder.glob("*/*"):
            try:
                stale_tmp = p.name.startswith(".") and p.name.endswith(".tmp") and \
                    now - p.lstat().st_mtime > STALE_TMP_S
                if stale_tmp or p.suffix == ".pkl":
                    p.unlink()
                    n += 1
            except OSError:
                continue
        return n

    def get(self, key: str):
        """The cached detections of ``key``, or None (absent, corrupt, planted)."""
        p = self._path(key)
        try:
            if p.is_symlink() or not p.is_file():
                return None
            data = p.read_bytes()
        except OSError:
            return None
        try:
            return decode_detections(data, key)
        except Exception as e:  # noqa: BLE001 - any bad entry is recomputed, never trusted
            log.info("cache entry %s ignored: %s", p.name, e)
            return None

    def put(self, key: str, value) -> None:
        try:
            atomic_write_bytes(self._path(key), encode_detections(value, key),
                               at_once=True)   # kept from a run that is stopped
        except OSError as e:
            log.warning("cache not written (%s): the next run measures this photo again", e)
