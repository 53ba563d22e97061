"""Pen marks: finding ink dots in a photo and measuring their centres on the sheet.

Two stages, so that the expensive pass over the whole photo can be cached and run in
parallel before the lens is known:

1. :func:`find_candidates` (whole photo, raw pixels, approximate mapping): ink is what
   darkens the *brightest* colour channel strongly (light coloured plotting-grid lines
   hardly do) relative to a local background (a morphological closing removes the dots,
   so smooth shadows and paper shading cancel). Marker squares with their quiet zones and
   everything off the paper are masked out using the mapping. Connected blobs are judged
   by size (against the area a ``pen.mark_diameter_mm`` dot has at that place in the
   photo), sheet-frame aspect and solidity; the survivors keep a small raw RGB patch.
2. :func:`refine_dot` (one patch, final mapping including the lens): the patch is resampled
   on a fine grid in *sheet* coordinates (0.05 mm), the background including the plotting
   grid is modelled as separable in log intensity (``log S = a(x) + b(y)``, robust medians
   outside the dot; grid lines are rows/columns of the sheet), and the centre is found from
   the centroid of the deficit ``bg - S`` in a disk around the dot: the photo is the blur
   of ``print (1 - a) + D a`` (``a`` the pen's cover, ``D`` its ink), so that centroid is
   the one of ``a (print - D)`` whatever the blur, and the pen's disk over the print says
   how far what it covers pulls it (:func:`_pen_over_print`). Because it is computed on a
   uniform sheet grid, perspective and lens do not bias it.

Uncertainty: white pixel noise (``sigma`` of the channel sum, estimated from the photo)
propagated through the centroid and through the background fit, plus the mapping's
covariance at the dot (homography fitted to the marker corners).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

import cv2
import numpy as np
from scipy.ndimage import gaussian_filter, grey_dilation, grey_erosion, maximum_filter1d

from vision_cal.config import DEFAULT, DotConfig
from vision_cal.dataset.photos import channel_sum
from vision_cal.dataset.session import Sheet
from vision_cal.measure.grid import nanmedian_columns
from vision_cal.measure.mapping import SheetMapping
from vision_cal.measure.printed import BLUR_CANDIDATES_PX
from vision_cal.dataset.marker_geometry import (marker_boxes_mm, marker_geometry, marker_side_mm,
                                                quiet_boxes_mm)
from vision_cal.model.rms import rms



def radii_mm(dia_mm: float, mm_per_px: float) -> tuple[float, float]:
    """(r_window, half_patch) in mm for a dot of ``dia_mm`` seen at ``mm_per_px``."""
    r_win = 0.5 * dia_mm * 1.2 + 2.5 * mm_per_px
    return r_win, r_win + max(0.8, 3.0 * mm_per_px)


@dataclass(frozen=True)
class DotCandidates:
    """Ink dots found in one photo (stage 1).

    ``uv_px`` (K, 2) raw-pixel blob centroids; ``patches`` K raw RGB uint8 patches and
    ``origins`` (K, 2) int the (col, row) of each patch's top-left pixel; ``area_px`` (K,);
    ``noise_sigma`` std of one pixel of the channel sum R+G+B (grey levels);
    ``rejected``: reason -> count; ``rejected_uv`` (R, 2) where they were.
    """

    uv_px: np.ndarray
    patches: tuple
    origins: np.ndarray
    area_px: np.ndarray
    noise_sigma: float
    rejected: dict = field(default_factory=dict)
    rejected_uv: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


_LAPLACE = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)


def noise_sigma_sum(rgb: np.ndarray, mapping: SheetMapping | None = None,
                    sheet: Sheet | None = None) -> float:
    """Robust per-pixel noise std of R+G+B (grey levels).

    Measured on blank paper, the white quiet zones around the markers (the plotting grid
    elsewhere would pass for noise), with a Laplacian-like 3x3 kernel (norm 6) that ignores
    smooth shading, and a median absolute value. Falls back to the whole image.
    """
    H, W = rgb.shape[:2]
    vals = []
    if mapping is not None and sheet is not None:
        geometry = marker_geometry(sheet)
        for m, box_mm in zip(sheet.markers, marker_boxes_mm(sheet)):
            lo, hi = box_mm[:2], box_mm[2:]
            outer = float(geometry.quiet_mm(marker_side_mm(m.corners_mm))) - 0.8
            inner = 0.8
            if outer <= inner:
                continue
            box = mapping.sheet_to_image(np.array([lo - outer, hi + outer, [lo[0] - outer, hi[1] + outer],
                                                   [hi[0] + outer, lo[1] - outer]]))
            u0, v0 = np.floor(box.min(axis=0)).astype(int) - 2
            u1, v1 = np.ceil(box.max(axis=0)).astype(int) + 3
            if u0 < 0 or v0 < 0 or u1 > W or v1 > H:
                continue
            crop = channel_sum(rgb[v0:v1, u0:u1])
            resp = cv2.filter2D(crop, -1, _LAPLACE)
            mk = np.zeros(crop.shape, np.uint8)
            for d, val in ((outer, 255), (inner, 0)):
                sq = np.array([[lo[0] - d, lo[1] - d], [hi[0] + d, lo[1] - d],
                               [hi[0] + d, hi[1] + d], [lo[0] - d, hi[1] + d]])
                poly = mapping.sheet_to_image(sq) - [u0, v0]
                cv2.fillPoly(mk, [np.round(poly * 16).astype(np.int32)], val, cv2.LINE_8, 4)
            mk[:1] = mk[-1:] = 0
            mk[:, :1] = mk[:, -1:] = 0
            vals.append(resp[mk > 0])
    v = np.concatenate(vals) if vals else np.zeros(0)
    if len(v) < 200:
        S = channel_sum(rgb[::2, ::2])
        v = cv2.filter2D(S, -1, _LAPLACE)[1:-1, 1:-1].ravel()
    return float(max(1.4826 * np.median(np.abs(v)) / 6.0, 0.3))


def _local_jac(mapping: SheetMapping, uv: np.ndarray) -> np.ndarray:
    """d sheet / d raw px (N, 2, 2) by central differences."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    e = 0.5
    pts = np.concatenate([uv + [e, 0], uv - [e, 0], uv + [0, e], uv - [0, e]])
    s = mapping.image_to_sheet(pts).reshape(4, -1, 2)
    J = np.empty((len(uv), 2, 2))
    J[:, :, 0] = (s[0] - s[1]) / (2 * e)
    J[:, :, 1] = (s[2] - s[3]) / (2 * e)
    return J


def _polygon(mapping: SheetMapping, corners_mm: np.ndarray, n: int = 12) -> np.ndarray:
    """Sheet polygon (closed, corners (M, 2)) as raw-pixel polygon with subdivided edges."""
    c = np.asarray(corners_mm, float)
    t = np.linspace(0, 1, n, endpoint=False)[:, None]
    pts = np.concatenate([c[i] + t * (c[(i + 1) % len(c)] - c[i]) for i in range(len(c))])
    return mapping.sheet_to_image(pts)


def sheet_mask(shape, mapping: SheetMapping, sheet: Sheet, *, border_mm: float = 2.0,
               margin_mm: float | None = None) -> np.ndarray:
    """uint8 (H, W) 255 where pen marks may be: on the paper, off markers and quiet zones
    (``margin_mm`` around each marker, default ``config.DotConfig.marker_margin_mm``)."""
    H, W = shape[:2]
    mask = np.zeros((H, W), np.uint8)
    x0, y0, x1, y1 = sheet.search_extent_mm
    b = border_mm
    paper = np.array([[x0 + b, y0 + b], [x1 - b, y0 + b], [x1 - b, y1 - b], [x0 + b, y1 - b]])
    poly = _polygon(mapping, paper, 24)
    cv2.fillPoly(mask, [np.round(poly * 16).astype(np.int32)], 255, cv2.LINE_8, 4)
    # the quiet zone is blank paper: dots there are measurable
    margin = DEFAULT.dots.marker_margin_mm if margin_mm is None else margin_mm
    for lo0, lo1, hi0, hi1 in marker_boxes_mm(sheet, margin):
        lo, hi = (lo0, lo1), (hi0, hi1)
        sq = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
        poly = _polygon(mapping, sq, 4)
        cv2.fillPoly(mask, [np.round(poly * 16).astype(np.int32)], 0, cv2.LINE_8, 4)
    return mask


def find_candidates(rgb: np.ndarray, mapping: SheetMapping, sheet: Sheet, *,
                    dia_mm: float | None = None,
                    config: DotConfig | None = None) -> DotCandidates:
    """Stage 1 on a whole colour photo (H, W, 3) uint8 (any channel order: only the
    channels' maximum and sum are used) with an approximate mapping. ``config``: the
    thresholds (default ``vision_cal.config.DEFAULT.dots``). The stages: the ink
    (:func:`_ink`), its blobs judged one by one (:func:`_judge_blob`), a patch cut around
    each that passes (:func:`_cut_patch`)."""
    cfg = config or DEFAULT.dots
    dia = float(dia_mm or cfg.default_diameter_mm)
    V, bg, ink = _ink(rgb, mapping, sheet, dia, cfg)
    try:
        n, labels, stats, cents = cv2.connectedComponentsWithStats(ink, connectivity=8,
                                                                   ltype=cv2.CV_16U)
    except cv2.error:  # more than 65535 blobs
        n, labels, stats, cents = cv2.connectedComponentsWithStats(ink, connectivity=8)
    sigma = noise_sigma_sum(rgb, mapping, sheet)
    uvs, patches, origins, areas = [], [], [], []
    rejected: dict[str, int] = {}
    rej_uv = []
    if n > 1:
        idx = np.arange(1, n)
        area = stats[idx, cv2.CC_STAT_AREA].astype(float)
        J = _local_jac(mapping, cents[idx])
        det = np.abs(np.linalg.det(J))  # mm^2 per px
        exp_area = np.pi * (dia / 2) ** 2 / np.maximum(det, 1e-12)
        ratio = area / exp_area
        for j, lab in enumerate(idx):
            uv = cents[lab]
            why = _judge_blob(ratio[j], labels, lab, stats[lab, :4], V, bg, J[j], cfg)
            if why is None:
                why = _cut_patch(rgb, uv, J[j], det[j], dia)
            if isinstance(why, str):
                if why:   # "": noise, paper texture: not worth a reason
                    rejected[why] = rejected.get(why, 0) + 1
                    rej_uv.append(uv)
                continue
            patch, origin = why
            patches.append(patch)
            origins.append(origin)
            uvs.append(uv)
            areas.append(area[j])
    return DotCandidates(np.asarray(uvs, float).reshape(-1, 2), tuple(patches),
                         np.asarray(origins, int).reshape(-1, 2), np.asarray(areas, float),
                         sigma, rejected, np.asarray(rej_uv, float).reshape(-1, 2))


def _ink(rgb: np.ndarray, mapping: SheetMapping, sheet: Sheet, dia: float, cfg: DotConfig):
    """(V the brightest channel, bg its local background, ink uint8 mask): ink is what
    darkens the brightest channel by ``cfg.ink_darkening`` of a closing that removes dots
    of ``dia`` mm, on the paper and off the markers (:func:`sheet_mask`)."""
    x0, y0, x1, y1 = sheet.search_extent_mm
    probe = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1], [(x0 + x1) / 2, (y0 + y1) / 2]])
    mmpp = mapping.mm_per_px(probe)
    dia_px_max = dia / max(float(mmpp.min()), 1e-6)
    k = int(2.4 * dia_px_max) + 3
    k += 1 - k % 2
    # numpy on the channel views: cv2.max copies each strided channel first (2x the time)
    V = np.maximum(np.maximum(rgb[:, :, 0], rgb[:, :, 1]), rgb[:, :, 2])
    bg = cv2.morphologyEx(V, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_RECT, (k, k)))
    thr = cv2.multiply(bg, 1.0 - cfg.ink_darkening, dtype=cv2.CV_8U)
    ink = cv2.compare(V, thr, cv2.CMP_LT)
    mask = sheet_mask(rgb.shape, mapping, sheet, margin_mm=cfg.marker_margin_mm)
    return V, bg, cv2.bitwise_and(ink, mask)


def _judge_blob(ratio: float, labels, lab: int, box, V, bg, J, cfg: DotConfig) -> str | None:
    """Why blob ``lab`` (bounding ``box`` (x, y, w, h), ``ratio`` its area over a dot's,
    ``J`` d sheet / d px at it) is no pen mark, "" for noise not worth a reason, None when
    it may be one: its size, its sheet-frame aspect (darkness-weighted second moments on the
    blob grown by a pixel, above the level printed lines reach: steadier than the
    thresholded pixels of a small dot) and its solidity."""
    if ratio < cfg.min_area_ratio:
        return ""
    if ratio > cfg.huge_area_ratio:
        return "too large for a pen mark (arm, shadow or print)"
    if ratio > cfg.max_area_ratio:
        return "too large for one mark (merged marks or smudge)"
    H, W = labels.shape
    xl, yt, w, h = box
    crop = (labels[yt:yt + h, xl:xl + w] == lab)
    y0_, x0_ = max(yt - 1, 0), max(xl - 1, 0)
    y1_, x1_ = min(yt + h + 1, H), min(xl + w + 1, W)
    grown = cv2.dilate((labels[y0_:y1_, x0_:x1_] == lab).astype(np.uint8),
                       np.ones((3, 3), np.uint8)) > 0
    bgc = bg[y0_:y1_, x0_:x1_].astype(float)
    dk = np.clip(bgc - V[y0_:y1_, x0_:x1_] - 0.2 * bgc, 0.0, None) * grown
    yy, xx = np.mgrid[y0_:y1_, x0_:x1_]
    sw = dk.sum()
    if sw > 0:
        mx, my = (dk * xx).sum() / sw, (dk * yy).sum() / sw
        C = np.array([[(dk * (xx - mx) ** 2).sum(), (dk * (xx - mx) * (yy - my)).sum()],
                      [0.0, (dk * (yy - my) ** 2).sum()]]) / sw
        C[1, 0] = C[0, 1]
        C += np.eye(2) / 12.0
    else:
        C = np.eye(2)
    ev = np.linalg.eigvalsh(J @ C @ J.T)
    if float(np.sqrt(ev[1] / max(ev[0], 1e-12))) > cfg.max_aspect:
        return "elongated (merged marks or smudge)"
    cnts, _ = cv2.findContours(np.pad(crop, 1).astype(np.uint8), cv2.RETR_EXTERNAL,
                               cv2.CHAIN_APPROX_NONE)
    cnt = max(cnts, key=len)
    a_c = cv2.contourArea(cnt)
    a_h = cv2.contourArea(cv2.convexHull(cnt))
    if a_h > 8 and a_c / a_h < cfg.min_solidity:
        return "irregular shape (smudge)"
    return None


def _cut_patch(rgb: np.ndarray, uv, J, det: float, dia: float):
    """(raw RGB patch, its top-left (col, row)) around a candidate at ``uv`` wide enough for
    :func:`refine_dot`'s window, or the reason it cannot be cut."""
    H, W = rgb.shape[:2]
    mm_px = float(np.sqrt(det))
    _, half_mm = radii_mm(dia, mm_px)
    smax = float(np.linalg.svd(J, compute_uv=False).min())  # mm per px, smallest
    hp = int(np.ceil(1.15 * half_mm / max(smax, 1e-6))) + 3
    cu, cv_ = int(round(uv[0])), int(round(uv[1]))
    if cu - hp < 0 or cv_ - hp < 0 or cu + hp + 1 > W or cv_ + hp + 1 > H:
        return "too close to the image edge"
    return (np.ascontiguousarray(rgb[cv_ - hp:cv_ + hp + 1, cu - hp:cu + hp + 1]),
            (cu - hp, cv_ - hp))


@dataclass(frozen=True)
class DotMeasurement:
    """A dot's centre ``xy_mm`` (2,) on the sheet and its covariance ``cov_mm2`` (2, 2)
    (noise + mapping), the noise's part ``cov_noise_mm2``."""

    xy_mm: np.ndarray
    cov_mm2: np.ndarray
    cov_noise_mm2: np.ndarray
    bg_residual: float = float("nan")  # background-model residual / noise (about 1 if clean)
    #: what is printed under the dot (labels of :class:`vision_cal.measure.printed.PrintedItem`,
    #: "" for bare paper and grid lines) and how the background was modelled: "separable"
    #: (paper and grid lines), "printed" (the sheet's own print rendered into the photo) or
    #: "previous photo" (the photo before, without the mark: a series adding marks)
    printed_under: str = ""
    background: str = "separable"
    #: why the centre cannot be trusted ("" when it can): the background model leaves more
    #: than ``config.dots.unreliable_bg_residual`` times the noise around it
    unreliable: str = ""
    #: flagged against the blank paper's noise, if not against the series' plain ground
    #: (``ground_scale``): the photo before is tried for it
    suspect: bool = False


def _resample(S: np.ndarray, origin, mapping: SheetMapping, centre, half, step):
    n = int(np.ceil(half / step))
    g = step * np.arange(-n, n + 1)
    X, Y = np.meshgrid(centre[0] + g, centre[1] + g)
    uv = mapping.sheet_to_image(np.column_stack([X.ravel(), Y.ravel()]))
    mx = (uv[:, 0] - origin[0]).reshape(X.shape).astype(np.float32)
    my = (uv[:, 1] - origin[1]).reshape(X.shape).astype(np.float32)
    out = cv2.remap(S, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                    borderValue=-1.0)
    return X, Y, out


def _fill(v: np.ndarray) -> np.ndarray:
    """Replace NaNs by the nearest valid value (linear in between)."""
    ok = np.isfinite(v)
    if ok.all() or not ok.any():
        return np.where(ok, v, 0.0)
    i = np.arange(len(v))
    return np.interp(i, i[ok], v[ok])


def blank_regions(sheet: Sheet) -> np.ndarray:
    """(K, 4) sheet rectangles [x0, y0, x1, y1] of bare paper: each marker with its quiet
    zone, as the sheet description says it was printed (:mod:`.marker_geometry`)."""
    return quiet_boxes_mm(sheet)


def refine_dot(patch_rgb: np.ndarray, origin, mapping: SheetMapping, xy0_mm, *,
               dia_mm: float | None = None, noise_sigma: float = 1.0,
               median_efficiency: float = 1.57, blank_rects=None,
               printed=None, previous=None, ground_scale: float = 1.0,
               config: DotConfig | None = None) -> DotMeasurement | None:
    """Stage 2: the dot's sheet centre from its raw patch with the final mapping
    (:func:`_refine_dot`). The photo before (``previous``) is the ground only where paper
    and grid lines do not explain it (the mark would be unreliable, or not measurable,
    without it): elsewhere it would add its own noise, blur and mapping error to a mark the
    separable model measures well (renders/small.yaml's closed loop: after-targets 0.099 mm
    RMS with it for every new mark, 0.051 mm with it only where needed, as before it).

    ``blank_rects`` (K, 4): sheet rectangles with no plotting grid (see
    :func:`blank_regions`). ``printed``: the sheet's own print
    (:class:`vision_cal.measure.printed.PrintedReference`); where it has more than the grid
    near the dot (axes, bars, text), the background is that print rendered into the patch
    (:func:`_printed_background`) instead of the separable model, and the centre is the
    pen's disk over the sharp print (:func:`_pen_over_print`), which the blur does not move.
    ``previous``: the photo before in a series that adds marks
    (:class:`vision_cal.measure.previous_photo.PreviousPhoto`); where the print is not
    described, and that photo shows the place without ink, the background is that photo
    (:func:`_previous_background`). Returns None when the dot cannot be measured (patch
    too small for the mapping, no ink, centroid running away).
    ``config``: the thresholds (default ``vision_cal.config.DEFAULT.dots``).
    """
    cfg = config or DEFAULT.dots
    o = _Given(float(dia_mm or cfg.default_diameter_mm), noise_sigma, median_efficiency,
               blank_rects, printed, None, ground_scale, cfg)
    first = _refine_dot(patch_rgb, origin, mapping, xy0_mm, o)
    if previous is None or (first is not None and not first.unreliable and not first.suspect):
        return first
    again = _refine_dot(patch_rgb, origin, mapping, xy0_mm, replace(o, previous=previous))
    return first if again is None else again


@dataclass(frozen=True)
class _Given:
    """What :func:`refine_dot` is given besides the patch and the mapping (its arguments)."""

    dia: float
    noise_sigma: float
    median_efficiency: float
    blank_rects: object
    printed: object
    previous: object
    ground_scale: float
    cfg: DotConfig


@dataclass(frozen=True)
class _Ground:
    """One model of the ground around a dot on its sheet grid: ``bg`` the background,
    ``P`` the paper's level, ``resid`` the log residual over the fitted samples,
    ``background`` its kind (:attr:`DotMeasurement.background`); over the sheet's own
    print also ``blur_alts`` (the neighbouring blurs' (bg, P)), ``sharp`` (the unblurred
    print) and ``blur_mm``."""

    bg: np.ndarray
    P: np.ndarray
    resid: np.ndarray
    background: str = "separable"
    blur_alts: tuple = ()
    sharp: np.ndarray | None = None
    blur_mm: float = 0.0


@dataclass(frozen=True)
class _Centre:
    """The pen's centre over one ground (:func:`_centre`): ``c`` (2,), the window ``win``,
    the ink's mass ``M`` (samples) and, over the sheet's own print, how far the centre
    moves with the ink's level, the print's blur and its edges (mm; the edges moved
    ``edge_mm``, as far as the photo allows, :func:`_edge_shift`)."""

    c: np.ndarray
    win: np.ndarray
    M: float
    d_shift: float = 0.0
    d_blur: float = 0.0
    d_edge: float = 0.0
    edge_mm: float = 0.0


def _refine_dot(patch_rgb: np.ndarray, origin, mapping: SheetMapping, xy0_mm,
                o: _Given) -> DotMeasurement | None:
    """One dot's centre with one model of the ground (:func:`refine_dot`): two passes of
    ground (:func:`_ground`) and centre (:func:`_centre`) on a sheet grid around the
    centre so far, then its covariance (:func:`_noise_cov`) and whether it can be trusted
    (:func:`_ring_pull`, :func:`_verdict`)."""
    cfg = o.cfg
    S = channel_sum(patch_rgb)
    c = np.asarray(xy0_mm, float).reshape(2)
    mm_px = float(mapping.mm_per_px(c)[0])
    r_win, half = radii_mm(o.dia, mm_px)
    step = min(cfg.fine_step_mm, mm_px / 4)
    under = [] if o.printed is None else o.printed.content_near(c, half + 0.5)
    gr = None
    for _pass in range(2):
        X, Y, Sg = _resample(S, origin, mapping, c, half, step)
        if np.any(Sg < 0):
            return None
        bgmask = np.hypot(X - c[0], Y - c[1]) > r_win
        gr = _ground(S, origin, mapping, X, Y, Sg, bgmask, c, half, step, mm_px, under, o, gr)
        fit = _centre(gr, Sg, X, Y, c, r_win, step, mm_px, o)
        if fit is None:
            return None
        t = Sg / gr.P
        shift = np.hypot(*(fit.c - c))
        c = fit.c
        if shift < 0.1 * r_win:
            break
    if np.hypot(*(c - np.asarray(xy0_mm, float).reshape(2))) > 0.5 * r_win:
        return None  # the centroid ran away from the blob: not a clean dot
    M_mm2 = float(fit.M * step * step)
    if M_mm2 < 0.1 * np.pi * (0.5 * o.dia) ** 2:
        return None  # hardly any ink
    sw2 = (o.noise_sigma / float(np.median(gr.bg))) ** 2 * mm_px**2  # per unit area
    cov_noise = _noise_cov(fit.win, t, bgmask, X - c[0], Y - c[1], step, sw2, M_mm2,
                           o.median_efficiency) + np.eye(2) * (cfg.model_floor_px * mm_px) ** 2
    cov_map = mapping.point_cov_mm2(c)[0]
    # what the separable background leaves unexplained, relative to the noise (diagnostic)
    noise_grid = np.sqrt(sw2) / mm_px  # per-sample std of the relative intensity (upper)
    ratio = rms(gr.resid) / noise_grid
    ring = (_ring_pull(gr, Sg, X, Y, c, r_win, o.dia, step, sw2, fit.M, M_mm2)
            if gr.background == "separable" else (0.0, 0.0))
    on = "; ".join(it.label for it in under)
    why, suspect = _verdict(gr.background, on, ratio, ring, fit, o)
    return DotMeasurement(c, cov_noise + cov_map, cov_noise,
                          ratio, on, gr.background, why, suspect)


def _separable_ground(L, X, Y, bgmask, step, blank_rects) -> _Ground:
    """The paper and grid lines around a dot, separable in log intensity
    (``log S = a(x) + b(y)``, robust medians over ``bgmask``), the paper's level their
    upper envelope. Blank paper (the markers' quiet zones, ``blank_rects``): the plotting
    grid ends there, which a separable model cannot follow; it is fitted on the ruled part
    and the bare paper level used inside."""
    blank = np.zeros(X.shape, bool)
    for x0, y0, x1, y1 in (() if blank_rects is None else blank_rects):
        blank |= (X >= x0) & (X <= x1) & (Y >= y0) & (Y <= y1)
    partial = blank.any() and not blank.all()
    fitmask = bgmask & ~blank if partial else bgmask
    if partial and (fitmask.sum(axis=0).max() == 0 or fitmask.sum(axis=1).max() == 0):
        partial, fitmask = False, bgmask
    Lm = np.where(fitmask, L, np.nan)
    a = np.zeros(X.shape[1])
    b = np.zeros(X.shape[0])
    with warnings.catch_warnings():  # columns / rows with no background sample
        warnings.simplefilter("ignore", RuntimeWarning)
        for _ in range(3):
            a = _fill(nanmedian_columns(Lm - b[:, None]))
            b = _fill(nanmedian_columns((Lm - a[None, :]).T))
    bg = np.exp(a[None, :] + b[:, None])
    resid = (L - a[None, :] - b[:, None])[fitmask]
    # paper level without printed lines: upper envelope of the separable model
    k_env = 2 * int(0.35 / step) + 1
    P = np.exp(maximum_filter1d(a, k_env, mode="nearest")[None, :]
               + maximum_filter1d(b, k_env, mode="nearest")[:, None])
    if partial:
        bg = np.where(blank, P, bg)
    return _Ground(bg, P, resid)


def _ground(S, origin, mapping, X, Y, Sg, bgmask, c, half, step, mm_px, under, o: _Given,
            before: _Ground | None) -> _Ground:
    """The ground of one pass: the sheet's own print where it describes more than the grid
    near the dot (``under``), else the photo before when given and usable, else paper and
    grid lines. What a model the pass before chose left (its kind, the sharp print and the
    blurs) stays when this pass's fit of it fails."""
    g = _separable_ground(np.log(np.maximum(Sg, 1.0)), X, Y, bgmask, step, o.blank_rects)
    if before is not None:
        g = replace(g, background=before.background, blur_alts=before.blur_alts,
                    sharp=before.sharp, blur_mm=before.blur_mm)
    if under:
        pb = _printed_background(S, origin, mapping, c, half, step, Sg, bgmask, o.printed,
                                 mm_px, o.noise_sigma)
        if pb is not None:
            bg, P, resid, blur_alts, sharp, blur_mm = pb
            return _Ground(bg, P, resid, "printed", blur_alts, sharp, blur_mm)
    elif o.previous is not None:
        pv = _previous_background(o.previous, X, Y, Sg, bgmask, c, o.dia, o.noise_sigma)
        if pv is not None:
            return replace(g, bg=pv[0], P=pv[1], resid=pv[2], background="previous photo")
    return g


def _centre(gr: _Ground, Sg, X, Y, c, r_win, step, mm_px, o: _Given) -> _Centre | None:
    """The pen's disk over what it covers (:func:`_pen_over_print`): the sharp print where
    the sheet describes it, else the ground model itself (paper and grid lines, blurred as
    the photo is); the pen's own level ``D`` is its darkest core. Over the print, how far
    the centre depends on what the model assumes: the ink's level (within the core's
    spread), the print's blur (the neighbouring candidates, which the photo tells apart only
    by a little) and its edges (:func:`_edge_shift`). None when there is no ink."""
    bg, P = gr.bg, gr.P
    r_dot = 0.5 * o.dia
    core = np.hypot(X - c[0], Y - c[1]) <= 0.5 * r_dot
    D = float(np.percentile(Sg[core], 10)) if core.any() else float(Sg.min())
    dD = float(np.percentile(Sg[core], 50)) - D if core.any() else 0.0
    printed = gr.background == "printed"
    under_pen = gr.sharp if printed else bg
    fw = _pen_over_print(bg - Sg, under_pen - D, X, Y, c, r_dot, r_win, step)
    if fw is None:
        return None
    cc, win, cover = fw
    M = cover * float(np.mean((P - D) / P))
    if not printed:
        return _Centre(cc, win, M)
    d_shift = d_blur = 0.0
    for Dp in (D - dD, D + dD):
        alt = _pen_over_print(bg - Sg, gr.sharp - Dp, X, Y, c, r_dot, r_win, step)
        if alt is not None:
            d_shift = max(d_shift, float(np.hypot(*(alt[0] - cc))))
    for bg_b, _P_b in gr.blur_alts:
        alt = _pen_over_print(bg_b - Sg, gr.sharp - D, X, Y, c, r_dot, r_win, step)
        if alt is not None:
            d_blur = max(d_blur, float(np.hypot(*(alt[0] - cc))))
    d_edge, edge_mm = _edge_shift(Sg, bg, gr.sharp, D, X, Y, c, cc, r_dot, r_win, step,
                                   gr.blur_mm,
                                   o.noise_sigma * max(float(o.ground_scale), 1.0),
                                   mm_px / step, o.cfg)
    return _Centre(cc, win, M, d_shift, d_blur, d_edge, edge_mm)


def _noise_cov(win, t, bgmask, dX, dY, step, sw2, M_mm2, median_efficiency):
    """The centre's covariance from the photo's white noise (``sw2`` per unit area): the
    pixels inside the window and the background's columns a(x) and rows b(y), each a
    median over its background samples (``median_efficiency`` its variance over a mean's)."""
    w2 = win * win
    cov_pix = np.array([[np.sum(w2 * dX * dX), np.sum(w2 * dX * dY)],
                        [np.sum(w2 * dX * dY), np.sum(w2 * dY * dY)]]) * step**2
    wt = win * t
    Lx = bgmask.sum(axis=0) * step
    Ly = bgmask.sum(axis=1) * step
    gx = np.stack([(wt * dX).sum(axis=0), (wt * dY).sum(axis=0)]) * step  # (2, nx)
    gy = np.stack([(wt * dX).sum(axis=1), (wt * dY).sum(axis=1)]) * step  # (2, ny)
    cov_bg = ((gx / np.maximum(Lx, step)) @ gx.T + (gy / np.maximum(Ly, step)) @ gy.T) * step
    return sw2 * (cov_pix + median_efficiency * cov_bg) / (M_mm2**2)


def _ring_pull(gr: _Ground, Sg, X, Y, c, r_win, dia, step, sw2, M, M_mm2):
    """(shift, its noise std per axis) in mm: ink the separable model does not explain just
    outside the window (print it cannot follow: a letter, a number, the corner of a label)
    goes on inside it, in the window's margin around the dot; its pull on the centroid,
    taken from a ring of the same width just outside the window."""
    if not M > 0:
        return 0.0, 0.0
    dX, dY = X - c[0], Y - c[1]
    rr = np.hypot(dX, dY)
    ring = (rr > r_win) & (rr <= 2.0 * r_win - 0.5 * dia)
    u = np.where(ring, (gr.bg - Sg) / gr.P, 0.0)
    shift = float(np.hypot((u * dX).sum(), (u * dY).sum()) / M)
    # ... beyond what the photo's noise alone gives it (per axis)
    sd = float(np.sqrt(sw2 * np.sum(ring * (dX * dX + dY * dY)) * step**2 / 2) / M_mm2)
    return shift, sd


def _verdict(background: str, on: str, ratio: float, ring, fit: _Centre, o: _Given
             ) -> tuple[str, bool]:
    """(why the centre cannot be trusted, "" when it can; suspect): the ground's residual
    beyond ``ratio`` limits (scaled by the series' plain ground), ink beside the window, or
    over the print a centre that moves with the ink's level, the blur or the edges. Suspect:
    what the blank paper's noise alone would have flagged, worth the photo before, which
    shows a print under the mark the series' plain ground may hide (a grid number)."""
    cfg = o.cfg
    ring_shift, ring_sd = ring
    why = ""
    g = max(float(o.ground_scale), 1.0)
    limit = g * (cfg.unreliable_bg_residual_separable if background == "separable"
                 else cfg.unreliable_bg_residual)
    if not ratio <= limit:
        what = (f"pen ink on printed ink ({on})" if on else
                "the ground around the mark is not paper and grid lines (printed ink, a blot "
                "or a neighbouring mark)")
        how = {"printed": "the sheet's own print rendered into the photo",
               "previous photo": "the photo before, without the mark"}.get(
                   background, "paper and grid lines")
        why = (f"{what} that could not be separated: {how} leave {ratio:.1f} times the "
               "noise around it" + (f" ({g:.1f} on this series' plain ground)" if g >= 1.05 else ""))
    elif ring_shift > max(cfg.unreliable_ink_shift_mm, cfg.unreliable_noise_sigmas * g * ring_sd):
        why = ("the ground around the mark is not paper and grid lines (printed ink, a blot "
               "or a neighbouring mark) that could not be separated: the ink beside it the "
               f"model does not explain would move the centre {1000 * ring_shift:.0f} um")
    elif background == "printed" and fit.d_shift > cfg.unreliable_ink_shift_mm:
        why = (f"pen ink on printed ink ({on}) that could not be separated: the centre "
               f"moves {1000 * fit.d_shift:.0f} um with the ink's level (within the spread "
               "of the dot's core)")
    elif background == "printed" and fit.d_blur > cfg.unreliable_ink_shift_mm:
        why = (f"pen ink on printed ink ({on}) that could not be separated: the centre "
               f"moves {1000 * fit.d_blur:.0f} um with the print's blur (one step of "
               "measure.printed.BLUR_CANDIDATES_PX)")
    elif background == "printed" and fit.d_edge > cfg.unreliable_ink_shift_mm:
        why = (f"pen ink on printed ink ({on}) that could not be separated: the centre "
               f"moves {1000 * fit.d_edge:.0f} um when the print's edges move "
               f"{1000 * fit.edge_mm:.0f} um, as far as the ground around it allows (another "
               "rasteriser, toner)")
    suspect = bool(why) or (g > 1 and background == "separable" and (
        ratio > cfg.unreliable_bg_residual_separable
        or ring_shift > max(cfg.unreliable_ink_shift_mm, cfg.unreliable_noise_sigmas * ring_sd)))
    return why, suspect


def ground_scale(ratios, backgrounds, printed_under, config: DotConfig | None = None
                 ) -> float:
    """How many times the photo's noise the plain ground leaves around the marks of a
    series: the ``config.ground_quantile`` quantile of the background residuals
    (``DotMeasurement.bg_residual``) of its dots modelled as paper and grid lines with
    nothing described under them, at least 1; 1 with
    fewer than ``config.ground_min_dots`` such dots. The photo's noise is measured on blank
    paper (the markers' quiet zones); JPEG flattens that paper and leaves its blocks and
    ringing on the grid lines, and lines a few pixels apart alias when resampled: on a
    JPEG at 0.35 mm per pixel (quality 85, a 1 mm grid) clean marks leave 2.6-3.8 times
    that noise where a PNG of the same view leaves 0.7-1.0. Marks on plain ground are a
    good part of any series (where the print is not described, ink under a mark is only
    known by its residual), so a low quantile is that ground's level; ink under a mark
    stands out of it (issue 28 section 4)."""
    cfg = config or DEFAULT.dots
    r = np.asarray([x for x, b, u in zip(ratios, backgrounds, printed_under)
                    if b == "separable" and not u and np.isfinite(x)], float)
    if len(r) < cfg.ground_min_dots:
        return 1.0
    return float(max(np.quantile(r, cfg.ground_quantile), 1.0))


def _robust_lstsq(A: np.ndarray, y: np.ndarray, noise_sigma: float):
    """(coef, residuals, kept) of ``y ~ A coef``: samples 3.5 robust std (at least the
    noise) off are left out, twice."""
    keep = np.ones(len(y), bool)
    for _ in range(3):
        coef, *_ = np.linalg.lstsq(A[keep], y[keep], rcond=None)
        r = y - A @ coef
        s = 1.4826 * float(np.median(np.abs(r[keep]))) + 1e-9
        keep = np.abs(r) < 3.5 * max(s, noise_sigma)
    return coef, r, keep


def _previous_background(previous, X, Y, Sg, bgmask, c, dia: float, noise_sigma: float):
    """(bg, P, log residual) from the photo before (``previous.sample`` on the dot's sheet
    grid), fitted as ``S = a + b S_before`` over the background samples (robust, as
    :func:`_printed_background`); ``P`` the paper's level (the bright end of the fitted
    background). None when the photo before does not hold the place, or already shows ink
    at the dot (the mark was there before: not a new mark)."""
    Sp = previous.sample(X, Y)
    if np.any(Sp < 0):
        return None
    y = Sg[bgmask].astype(float)
    A = np.column_stack([np.ones(len(y)), Sp[bgmask]])
    if len(y) < 20:
        return None
    coef, _, _ = _robust_lstsq(A, y, noise_sigma)
    bg = coef[0] + coef[1] * Sp
    if not coef[1] > 0 or np.any(bg <= 0):
        return None
    P = float(np.percentile(bg[bgmask], 95))
    # ink already there before: the core is as dark in the photo before as in this one
    core = np.hypot(X - c[0], Y - c[1]) <= 0.25 * dia
    if not core.any() or float(np.median(bg[core] - Sg[core])) < 0.25 * P:
        return None
    resid = (np.log(np.maximum(Sg, 1.0)) - np.log(bg))[bgmask]
    return bg, np.full(Sg.shape, P), resid


def _pen_over_print(F, contrast, X, Y, c0, r_dot: float, r_win: float, step: float):
    """The centre of a pen dot over the print: (centre (2,), window (h, w), ink cover in
    samples), None when there is no ink.

    The photo is the blur of ``T (1 - a) + D a`` (``a`` the pen's cover, ``T`` the sharp
    print, ``D`` the ink's level), so the deficit ``F = bg - S`` is the blur of
    ``a (T - D)`` and its centroid is the one of ``a (T - D)`` whatever the blur. A disk of
    the pen's size (scaled to ``F``'s mass) over ``contrast = T - D`` gives how far the
    print pulls that centroid off the disk's centre; the centre is moved back by as much.
    """
    cc = np.asarray(c0, float).copy()
    k = np.clip(contrast, 0.0, None)
    for _ in range(12):
        rc = np.hypot(X - cc[0], Y - cc[1])
        win = (rc <= r_win).astype(float)
        MF = float((win * F).sum())
        if MF <= 0:
            return None
        c1 = np.array([(win * F * X).sum(), (win * F * Y).sum()]) / MF
        disk = np.clip((r_dot - rc) / step + 0.5, 0.0, 1.0)
        m = win * disk * k
        r_eff = r_dot * np.sqrt(min(max(MF / max(m.sum(), 1e-9), 0.25), 4.0))
        disk = np.clip((r_eff - rc) / step + 0.5, 0.0, 1.0)
        m = win * disk * k
        if m.sum() <= 0:
            return None
        cm = np.array([(m * X).sum(), (m * Y).sum()]) / m.sum()
        new = c1 - (cm - cc)
        moved = float(np.hypot(*(new - cc)))
        cc = new
        if moved < 1e-5:
            break
    cover = MF / max(float(m.sum() / max(disk.sum(), 1e-9)), 1e-9)
    return cc, win, cover


def _edge_shift(Sg, bg, sharp, D, X, Y, c, cc, r_dot, r_win, step, blur_mm, noise: float,
                px_per_step: float, cfg: DotConfig) -> tuple[float, float]:
    """(shift, edge) mm: how far the centre moves when the print's edges move as far as the
    photo allows (``edge``), at most ``cfg.printed_edge_mm`` from where the layout puts
    them (its ink grown or thinned: another rasteriser of the same PDF, toner, a font drawn
    by other code).

    For each side (grown, thinned by ``printed_edge_mm``) the centre's move ``d`` (the sharp
    print moved, the blurred print moved with it at the fitted blur) and the photo's say on
    it: the ground around the dot (outside the window) fitted with the moved print and with
    the print as laid out, each at its best blur of
    :data:`vision_cal.measure.printed.BLUR_CANDIDATES_PX` and level (a blur and a contrast
    can stand for a grown stroke), the moved print's excess residual ``chi2`` over the
    variance (the residual's level, at least the photo's noise, over the samples a pixel
    holds). The edges may move the fraction ``sqrt(cfg.printed_edge_chi2 / chi2)`` of the
    way there (at most all of it: the residual grows with the square of a small move), and
    the centre moves that fraction of ``d``. A centre that moves more than
    ``unreliable_ink_shift_mm`` so is unreliable: print under the pen that the ground
    around it does not pin (issue 28 section 4: on photos of a rendering of the project's
    PDF, a mark on a bar's edge 35 um off and marks on letters and numbers 40-60 um off,
    none flagged before any edge move was counted; the sheet's own raster's marks on text
    2-13 um off, all flagged with every move counted whole, though the ground there fits
    no other edges)."""
    n = max(1, int(round(cfg.printed_edge_mm / step)))
    size = (2 * n + 1, 2 * n + 1)
    ring = np.hypot(X - c[0], Y - c[1]) > r_win
    y = Sg[ring].astype(float)
    A1 = np.ones(len(y))
    mm_px = px_per_step * step

    def misfit(s_):   # the ground's least residual with the sharp print s_, any blur
        best = np.inf
        for k in BLUR_CANDIDATES_PX:
            m = gaussian_filter(s_, k * mm_px / step, mode="nearest")[ring]
            A = np.column_stack([A1, m])
            coef, *_ = np.linalg.lstsq(A, y, rcond=None)
            best = min(best, float(np.sum((y - A @ coef) ** 2)))
        return best

    ss0 = misfit(sharp)
    var = max(float(noise) ** 2, ss0 / max(len(y), 1)) * px_per_step ** 2
    shift = edge = 0.0
    for op in (grey_erosion, grey_dilation):
        sharp_e = op(sharp, size=size)
        moved = gaussian_filter(sharp_e - sharp, blur_mm / step, mode="nearest")
        alt = _pen_over_print(bg + moved - Sg, sharp_e - D, X, Y, c, r_dot, r_win, step)
        if alt is None:
            continue
        d = float(np.hypot(*(alt[0] - cc)))
        chi2 = max(misfit(sharp_e) - ss0, 0.0) / var
        reach = float(min(1.0, np.sqrt(cfg.printed_edge_chi2 / max(chi2, 1e-12))))
        if reach * d > shift:
            shift, edge = reach * d, reach * cfg.printed_edge_mm
    return shift, edge


def _printed_background(S, origin, mapping: SheetMapping, c, half, step, Sg, bgmask, printed,
                        mm_px, noise_sigma):
    """(bg, P, log residual, alternatives, sharp, blur mm) of the print around a dot: the sheet's own
    print rendered into the patch's raw pixels (:meth:`PrintedReference.predict_patch`) and
    resampled like the photo, the photo's level fitted as ``S = a + sum_c b_c T_c`` over the background
    samples (robust: samples 3.5 robust std off are left out, twice). The blur is the one of
    :data:`vision_cal.measure.printed.BLUR_CANDIDATES_PX` that fits best. ``P`` is the bare
    paper's level (every ``T_c`` = 1); ``alternatives`` the (bg, P) of the neighbouring
    blurs the photo cannot tell from the best; ``sharp`` the fitted level of the unblurred
    print (what the pen covers). None when the fit cannot be made."""
    fits = []
    y = Sg[bgmask].astype(float)
    if len(y) < 20:
        return None
    for k in BLUR_CANDIDATES_PX:
        T = printed.predict_patch(mapping, origin, S.shape, c, half, k * mm_px)
        Tg = np.stack([_resample(t, origin, mapping, c, half, step)[2] for t in T])
        A = np.column_stack([np.ones(len(y))] + [t[bgmask] for t in Tg])
        coef, r, keep = _robust_lstsq(A, y, noise_sigma)
        score = float(np.mean(r[keep] ** 2)) * len(y) / max(keep.sum(), 1) ** 1
        fits.append((score, coef, Tg))
    i = int(np.argmin([f[0] for f in fits]))
    out = []
    for j in (i, i - 1, i + 1):
        if not 0 <= j < len(fits):
            continue
        # a neighbouring blur counts when the photo cannot tell it from the best one: its
        # residual sum of squares exceeds the best's by less than 4 noise variances (2 sigma)
        if j != i and (fits[j][0] - fits[i][0]) * len(y) > 4.0 * noise_sigma ** 2:
            continue
        _, coef, Tg = fits[j]
        bg = coef[0] + np.tensordot(coef[1:], Tg, axes=1)
        P = float(coef.sum())
        if not np.isfinite(P) or P <= 0 or np.any(bg <= 0):
            if j == i:
                return None
            continue
        out.append((bg, P))
    bg, P = out[0]
    resid = (np.log(np.maximum(Sg, 1.0)) - np.log(bg))[bgmask]
    coef = fits[i][1]
    X, Y, _ = _resample(S, origin, mapping, c, half, step)
    sharp = coef[0] + np.tensordot(coef[1:], printed.transmission_at(X, Y), axes=1)
    return bg, np.full(Sg.shape, P), resid, out[1:], sharp, BLUR_CANDIDATES_PX[i] * mm_px
