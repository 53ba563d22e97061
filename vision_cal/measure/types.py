"""The measurement's types: what stage 1 finds in a photo, what a measured photo and a
measured mark are, the whole measurement, and their JSON.

``ImageDetections`` (stage 1, cached by :mod:`vision_cal.measure.cache`), ``ImageResult``
(one photo measured), ``MarkMeasurement`` (one pen mark on the sheet) and ``Measurement``
(everything :func:`vision_cal.actions.measure_folder.measure_folder` returns).
``OUT/measurement.json`` (docs/format.md) is written by ``Measurement.write`` alone and read
by ``Measurement.read`` alone (the report reads it so: the photos, the refused marks, the
sheet as printed; ``tests/test_architecture.py`` finds any other reader or writer);
``ImageResult.summary_json`` is a photo's entry of calibration.json ``images[]``.

Arrays: ``(K, 2)`` sheet mm or raw px per dot, ``(K, 2, 2)`` covariances (mm^2),
``(M, 4, 2)`` marker corners (raw px), ``(M,)`` marker ids.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from vision_cal.dataset.fields import FieldReader
from vision_cal.dataset.io import atomic_write_json, read_json
from vision_cal.measure.aruco import corners_from_edges
from vision_cal.measure.asprinted import AsPrinted
from vision_cal.measure.dots import DotCandidates
from vision_cal.measure.height import HeightMap, MarkHeight
from vision_cal.measure.mapping import LensEstimate, SheetMapping, distort_px, undistort_px

#: ``format`` of measurement.json
FORMAT = "vision-cal/measurement/1"


def _a(v, shape_tail=(), dtype=float) -> np.ndarray:
    """A JSON list back to an array of ``(-1, *shape_tail)`` (None -> NaN)."""
    if v is None:
        v = []
    return np.asarray(v, dtype=dtype).reshape((-1, *shape_tail))


def _opt(v, shape=None):
    return None if v is None else np.asarray(v, float).reshape(shape) if shape else \
        np.asarray(v, float)


def _list(v):
    return None if v is None else np.asarray(v).tolist()

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
    # the print's displacement where the markers were measured as printed (a survey or
    # several places: :class:`vision_cal.measure.grid_print.GridPrint`; None: not measured),
    # the grid reference's correction; set by the as-printed stage, never cached
    grid_print: object | None = None

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


def dot_field(im: "ImageResult", name: str, j: int) -> str:
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

    #: added after association: per dot the id of the mark it was taken for ("" for none)
    dots_mark: tuple = ()
    #: per dot the background model's residual / noise and the model (``DotMeasurement``
    #: ``bg_residual``, ``background``): the series' plain-ground level
    dots_bg_residual: tuple = ()
    dots_background: tuple = ()
    dots_suspect: tuple = ()        # DotMeasurement.suspect
    #: dots seen but not refined (issue 33, :mod:`vision_cal.measure.views`): refined in
    #: enough earlier photos; their blob centroids through this photo's mapping (S, 2) and
    #: in pixels (S, 2): for grouping and inference only, not in ``n_dots``
    seen_xy_mm: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    seen_uv_px: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    def summary_json(self) -> dict:
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

    def to_json(self) -> dict:
        """The photo's entry of measurement.json ``images[]``: everything, read back by
        :meth:`from_json` (the calibration.json entry's fields first, unrounded)."""
        return {"file": self.file, "status": self.status, "reason": self.reason,
                "n_markers": self.n_markers, "corner_rms_px": float(self.corner_rms_px),
                "corner_rms_mm": float(self.corner_rms_mm), "n_dots": self.n_dots,
                "rejected_blobs": dict(self.rejected), "noise_sigma": float(self.noise_sigma),
                "size_px": None if self.size_px is None else [int(v) for v in self.size_px],
                "from_cache": bool(self.from_cache),
                "marker_ids": [int(v) for v in np.asarray(self.marker_ids).ravel()],
                "markers_px": np.asarray(self.markers_px, float).tolist(),
                "K": _list(self.K),
                "mapping": None if self.mapping is None else self.mapping.to_json(),
                "dots": {"xy_mm": np.asarray(self.dots_xy_mm).tolist(),
                         "cov_mm2": np.asarray(self.dots_cov_mm2).tolist(),
                         "uv_px": np.asarray(self.dots_uv_px).tolist(),
                         "global_xy_mm": np.asarray(self.dots_global_xy_mm).tolist(),
                         "global_cov_mm2": np.asarray(self.dots_global_cov_mm2).tolist(),
                         "grid_offset_mm": np.asarray(self.dots_grid_offset_mm).tolist(),
                         "grid_offset_cov_mm2":
                             np.asarray(self.dots_grid_offset_cov_mm2).tolist(),
                         "reference": list(self.dots_reference),
                         "unreliable": list(self.dots_unreliable),
                         "printed_under": list(self.dots_printed_under),
                         "mark": list(self.dots_mark),
                         "bg_residual": [None if not np.isfinite(v) else float(v)
                                         for v in self.dots_bg_residual],
                         "background": list(self.dots_background),
                         "suspect": [bool(v) for v in self.dots_suspect]},
                "dots_seen": {"xy_mm": np.asarray(self.seen_xy_mm).tolist(),
                              "uv_px": np.asarray(self.seen_uv_px).tolist()}}

    @classmethod
    def from_json(cls, d: dict) -> "ImageResult":
        """Back from :meth:`to_json`."""
        dots = d.get("dots") or {}
        size = d.get("size_px")
        nan = float("nan")
        return cls(
            d["file"], d["status"], d.get("reason"), int(d.get("n_markers", 0)),
            nan if d.get("corner_rms_px") is None else float(d["corner_rms_px"]),
            nan if d.get("corner_rms_mm") is None else float(d["corner_rms_mm"]),
            int(d.get("n_dots", 0)), _a(dots.get("xy_mm"), (2,)),
            _a(dots.get("cov_mm2"), (2, 2)), _a(dots.get("uv_px"), (2,)),
            dict(d.get("rejected_blobs") or {}),
            nan if d.get("noise_sigma") is None else float(d["noise_sigma"]),
            None if size is None else (int(size[0]), int(size[1])),
            bool(d.get("from_cache", False)), _a(d.get("marker_ids"), (), int),
            _a(d.get("markers_px"), (4, 2)), _a(dots.get("global_xy_mm"), (2,)),
            _a(dots.get("grid_offset_mm"), (2,)), tuple(dots.get("reference") or ()),
            _a(dots.get("global_cov_mm2"), (2, 2)), _a(dots.get("grid_offset_cov_mm2"), (2, 2)),
            None if d.get("mapping") is None else SheetMapping.from_json(d["mapping"]),
            _opt(d.get("K"), (3, 3)), tuple(dots.get("unreliable") or ()),
            tuple(dots.get("printed_under") or ()), tuple(dots.get("mark") or ()),
            tuple(float("nan") if v is None else float(v)
                  for v in dots.get("bg_residual") or ()),
            tuple(dots.get("background") or ()),
            tuple(bool(v) for v in dots.get("suspect") or ()),
            _a((d.get("dots_seen") or {}).get("xy_mm"), (2,)),
            _a((d.get("dots_seen") or {}).get("uv_px"), (2,)))


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

    def to_json(self) -> dict:
        """The mark's entry of measurement.json ``marks`` (without its height)."""
        return {"measured_mm": np.asarray(self.xy_mm, float).tolist(),
                "cov_mm2": np.asarray(self.cov_mm2, float).tolist(),
                "n_photos": self.n_photos, "spread_mm": self.spread_mm, "how": self.how,
                "files": list(self.files), **mark_reference_json(self)}

    @classmethod
    def from_json(cls, d: dict) -> "MarkMeasurement":
        lmg, sd = d.get("local_minus_global_mm"), d.get("local_minus_global_std_mm")
        return cls(np.asarray(d["measured_mm"], float), np.asarray(d["cov_mm2"], float),
                   int(d["n_photos"]),
                   float("nan") if d.get("spread_mm") is None else float(d["spread_mm"]),
                   d.get("how", "model"), tuple(d.get("files") or ()),
                   d.get("reference", "markers"), _opt(lmg), _opt(sd),
                   d.get("status", "ok"), d.get("reason", ""), d.get("printed_under", ""))


@dataclass(frozen=True)
class Measurement:
    """Every photo measured (``images``: :class:`ImageResult` list, folder order) and every
    mark found (``marks``: id -> :class:`MarkMeasurement`), the lens, the sheet's height."""

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
    heights: dict = field(default_factory=dict)     # id -> measure.height.MarkHeight
    height_map: HeightMap | None = None
    height_note: str | None = None
    #: the dataset folder the photos are in (``images[].file`` is relative to it)
    dataset: str | None = None
    #: the sheet as printed (#28: :class:`vision_cal.measure.asprinted.AsPrinted`), when a
    #: survey or several camera places gave it; ``print_summary``: measurement.json ``print``
    as_printed: object | None = None
    print_summary: dict | None = None

    def session_images(self) -> list[dict]:
        """``images`` for session.json: every usable photo and the marks it shows."""
        return [{"file": im.file, "marks": list(ms)}
                for im, ms in zip(self.images, self.image_marks) if im.status == "ok"]

    def images_json(self) -> list[dict]:
        """calibration.json ``images[]``: each photo's summary."""
        return [im.summary_json() for im in self.images]

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
        """``OUT/measurement.json`` (docs/format.md), read back by :meth:`from_json`."""
        return {"format": FORMAT, "dataset": self.dataset,
                "marks": {k: {**m.to_json(), **(self.heights[k].to_json()
                                                if k in self.heights else {})}
                          for k, m in self.marks.items()},
                "images": [im.to_json() for im in self.images],
                "effects": self.effects_json(),
                "lens": None if self.lens is None else self.lens.to_json(),
                "unassigned": self.unassigned, "refused": self.refused,
                "warnings": self.warnings, "inferred": self.inferred,
                "inferred_notes": list(self.inferred_notes),
                "image_marks": [list(m) for m in self.image_marks],
                "sheet_height": (self.height_map.to_json(decimals=None)
                                 if self.height_map is not None
                                 else {"claimed": False, "note": self.height_note}),
                "heights": {k: h.to_full_json() for k, h in self.heights.items()},
                "height_note": self.height_note,
                "as_printed": None if self.as_printed is None else self.as_printed.to_json(),
                "print": self.print_summary}

    def write(self, path) -> Path:
        """measurement.json, atomically (nothing half-written): its one writer."""
        return atomic_write_json(Path(path), self.to_json())

    @classmethod
    def read(cls, path) -> "Measurement":
        """measurement.json at ``path``, its one reader: the format checked (one line
        naming the file and the field), then :meth:`from_json`."""
        d = read_json(Path(path), what="measurement")
        fmt = FieldReader(str(path)).get(d, "format", "")
        if fmt != FORMAT:
            FieldReader(str(path)).fail("format", f"expected {FORMAT!r}, got {fmt!r}")
        return cls.from_json(d)

    @classmethod
    def from_json(cls, d: dict) -> "Measurement":
        """Back from :meth:`to_json` (measurement.json)."""
        sh = d.get("sheet_height") or {}
        return cls({k: MarkMeasurement.from_json(m) for k, m in (d.get("marks") or {}).items()},
                   [ImageResult.from_json(im) for im in d.get("images") or []],
                   None if d.get("lens") is None else LensEstimate.from_json(d["lens"]),
                   list(d.get("unassigned") or []), dict(d.get("refused") or {}),
                   list(d.get("warnings") or []),
                   tuple(tuple(m) for m in d.get("image_marks") or ()), d.get("inferred"),
                   tuple(d.get("inferred_notes") or ()),
                   {k: MarkHeight.from_json(h) for k, h in (d.get("heights") or {}).items()},
                   HeightMap.from_json(sh) if "grid" in sh else None,
                   d.get("height_note", sh.get("note")), d.get("dataset"),
                   None if d.get("as_printed") is None else AsPrinted.from_json(d["as_printed"]),
                   d.get("print"))


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

