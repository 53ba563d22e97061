"""Finding the session's ArUco markers in a photograph.

Returns the markers that belong to ``session.sheet`` with their four corners in raw image
pixels (OpenCV order TL, TR, BR, BL, the same order as ``SheetMarker.corners_mm``), and
decides whether the photo shows enough of the sheet to fix a mapping.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from vision_cal.config import DEFAULT, MarkerConfig
from vision_cal.dataset.session import Sheet
from vision_cal.dataset.marker_geometry import MarkerGeometry

#: dictionaries tried (only after a failure) to tell "another sheet" from "no sheet"
_PROBE_DICTS = ("DICT_4X4_1000", "DICT_5X5_1000", "DICT_6X6_1000", "DICT_7X7_1000",
                "DICT_ARUCO_ORIGINAL", "DICT_APRILTAG_36h11")


@lru_cache(maxsize=16)
def _detector(dictionary: str) -> cv2.aruco.ArucoDetector:
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    p = cv2.aruco.DetectorParameters()
    p.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    p.cornerRefinementWinSize = 5
    p.relativeCornerRefinmentWinSize = 0.3
    p.cornerRefinementMaxIterations = 60
    p.cornerRefinementMinAccuracy = 0.005
    return cv2.aruco.ArucoDetector(d, p)


def detect_raw(gray: np.ndarray, dictionary: str) -> tuple[np.ndarray, np.ndarray]:
    """All markers of ``dictionary``: ids (M,) int and corners (M, 4, 2) raw px float64."""
    corners, ids, _ = _detector(dictionary).detectMarkers(gray)
    return _as_arrays(ids, corners)


def _as_arrays(ids, corners) -> tuple[np.ndarray, np.ndarray]:
    if ids is None or len(ids) == 0:
        return np.zeros(0, int), np.zeros((0, 4, 2))
    ids = np.asarray(ids).reshape(-1).astype(int)
    c = np.asarray(corners, dtype=np.float64).reshape(len(ids), 4, 2)
    return ids, c


def detect_with_layout(gray: np.ndarray, sheet: Sheet) -> tuple[np.ndarray, np.ndarray]:
    """The sheet's markers found again with its layout (issue 37): OpenCV's
    ``refineDetectedMarkers`` projects the markers not found through the homography of
    those found and reads the rejected candidates at their places, with OpenCV's default
    tolerance for their bits (a candidate must lie where the layout puts that id). Small
    markers seen obliquely (a real ChArUco board, 30 px markers tilted 50 deg: 6 of 17
    read, all 17 here) lose bits the plain detector will not correct."""
    det = _detector(sheet.aruco_dictionary)
    corners, ids, rejected = det.detectMarkers(gray)
    if ids is None or len(ids) == 0:
        return _as_arrays(ids, corners)
    obj = [np.column_stack([np.asarray(m.corners_mm, np.float32).reshape(4, 2),
                            np.zeros(4, np.float32)]) for m in sheet.markers]
    board = cv2.aruco.Board(obj, det.getDictionary(),
                            np.array([int(m.id) for m in sheet.markers], np.int32))
    corners, ids, _, _ = det.refineDetectedMarkers(gray, board, corners, ids, rejected)
    return _as_arrays(ids, corners)


@dataclass(frozen=True)
class MarkerDetection:
    """Markers of the session's sheet seen in one photo.

    ``ids`` (M,); ``corners_px`` (M, 4, 2) raw pixels; ``corners_mm`` (M, 4, 2) sheet mm;
    ``n_foreign`` markers of the dictionary that are not on the sheet; ``reason`` is None
    when the photo shows enough of the sheet, else why not (one line).
    """

    ids: np.ndarray
    corners_px: np.ndarray
    corners_mm: np.ndarray
    n_foreign: int
    reason: str | None


def find_sheet_markers(gray: np.ndarray, sheet: Sheet, *,
                       config: MarkerConfig | None = None) -> MarkerDetection:
    """The sheet's markers in a grey photo; ``reason`` set when too few or another sheet's
    (thresholds: ``config``, default ``vision_cal.config.DEFAULT.markers``)."""
    cfg = config or DEFAULT.markers
    ids, c = detect_raw(gray, sheet.aruco_dictionary)
    found = _sheet_markers(gray, sheet, ids, c, cfg)
    if found.reason is not None and len(found.ids) and not found.reason.startswith("wrong"):
        # refused for too few markers where some of the sheet's were read: the others
        # are looked for where the layout puts them before the photo is refused
        found = _sheet_markers(gray, sheet, *detect_with_layout(gray, sheet), cfg)
    return found


def _sheet_markers(gray: np.ndarray, sheet: Sheet, ids: np.ndarray, c: np.ndarray,
                   cfg: MarkerConfig) -> MarkerDetection:
    """The markers ``ids``, ``c`` that are the sheet's, and the reason the photo is refused
    (None: kept)."""
    by_id = sheet.corners_by_id()
    keep = np.array([int(i) in by_id for i in ids], dtype=bool)
    # a marker id seen twice is not trusted
    uniq, counts = np.unique(ids[keep], return_counts=True)
    dup = set(uniq[counts > 1].tolist())
    keep &= np.array([int(i) not in dup for i in ids], dtype=bool)
    n_foreign = int((~np.array([int(i) in by_id for i in ids], dtype=bool)).sum()) if len(ids) else 0
    ids_k, c_k = ids[keep], c[keep]
    mm = np.array([by_id[int(i)] for i in ids_k]).reshape(-1, 4, 2)
    reason = None
    n = len(ids_k)
    if n_foreign >= 2 and n_foreign > n:
        reason = (f"wrong sheet: {n_foreign} {sheet.aruco_dictionary} markers are not on this "
                  f"sheet, {n} are")
    elif n < cfg.min_markers:
        other = _probe_other_dictionaries(gray, sheet.aruco_dictionary) if n == 0 else None
        if other:
            reason = f"wrong sheet: {other}, none of this sheet's {sheet.aruco_dictionary}"
        else:
            reason = (f"too few markers: {n} of the sheet's markers found, "
                      f"at least {cfg.min_markers} needed")
    else:
        pts = c_k.reshape(-1, 2).astype(np.float32)
        hull = cv2.convexHull(pts)
        area = float(cv2.contourArea(hull))
        frac = area / float(gray.shape[0] * gray.shape[1])
        if frac < cfg.min_hull_fraction:
            reason = (f"too few markers: the {n} markers found cover {100 * frac:.1f} % of "
                      f"the image, at least {100 * cfg.min_hull_fraction:.0f} % needed")
    return MarkerDetection(ids_k, c_k, mm, n_foreign, reason)


def _probe_other_dictionaries(gray: np.ndarray, own: str) -> str | None:
    """Name markers of another dictionary in the photo, if any (only on the failure path)."""
    for name in _PROBE_DICTS:
        if name[:9] == own[:9]:  # same bit size as the sheet's: already tried
            continue
        ids, _ = detect_raw(gray, name)
        if len(ids) >= 2:
            return f"found {len(ids)} {name} markers"
    return None


# --------------------------------------------------------------------------- corner refinement

N_EDGE = 16


def edge_points(gray: np.ndarray, corners_px: np.ndarray, *, geometry: MarkerGeometry,
                n: int = N_EDGE) -> np.ndarray:
    """Sub-pixel points on the outer edges of each marker's black border.

    ``corners_px`` (M, 4, 2) rough corners. For each side (corner k to k+1) ``n`` points
    along its middle 76 % are moved along the side's normal onto the dark-to-bright
    mid-level crossing of a bilinear profile (unbiased for any symmetric blur). The
    profile reaches 0.45 of a module (or of the quiet zone, if narrower) either side of
    the edge: inside the black border module and the white quiet zone, from ``geometry``
    (:func:`vision_cal.dataset.marker_geometry.marker_geometry` of the session's sheet).
    Returns (M, 4, n, 2) raw pixels, NaN where no crossing was found.
    """
    c = np.asarray(corners_px, float).reshape(-1, 4, 2)
    M = len(c)
    if M == 0:
        return np.zeros((0, 4, n, 2))
    a = c
    b = np.roll(c, -1, axis=1)
    side = np.linalg.norm(b - a, axis=2)  # (M, 4)
    d = (b - a) / np.maximum(side[..., None], 1e-9)
    nrm = np.stack([d[..., 1], -d[..., 0]], axis=-1)
    centre = c.mean(axis=1)[:, None, :]
    mid = 0.5 * (a + b)
    flip = np.sum((mid - centre) * nrm, axis=-1) < 0
    nrm[flip] *= -1.0  # outward
    module = side.mean(axis=1) / geometry.modules_per_side  # px per module (approx.)
    reach = module * min(1.0, geometry.quiet_modules)       # stay in border and quiet zone
    L = np.clip(0.45 * reach, 1.5, 4.0)[:, None]  # (M, 1)
    t = np.linspace(0.12, 0.88, n)
    s_unit = np.linspace(-1.0, 1.0, 33)
    P = a[:, :, None, :] + t[None, None, :, None] * (b - a)[:, :, None, :]  # (M,4,n,2)
    S = s_unit[None, None, None, :] * L[:, :, None, None]  # (M,1,1,33)
    S = np.broadcast_to(S, (M, 4, n, 33))
    Q = P[..., None, :] + S[..., None] * nrm[:, :, None, None, :]  # (M,4,n,33,2)
    mx = Q[..., 0].reshape(-1, 33).astype(np.float32)
    my = Q[..., 1].reshape(-1, 33).astype(np.float32)
    prof = cv2.remap(gray.astype(np.float32), mx, my, cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=-1.0)
    prof = prof.reshape(M, 4, n, 33).astype(float)
    dark = prof[..., :5].mean(axis=-1)
    bright = prof[..., -5:].mean(axis=-1)
    level = 0.5 * (dark + bright)
    above = prof >= level[..., None]
    # first crossing from dark to bright
    idx = np.argmax(above, axis=-1)
    ok = (idx > 0) & (bright - dark > 20) & np.all(prof >= 0, axis=-1)
    idx = np.clip(idx, 1, 32)
    p1 = np.take_along_axis(prof, idx[..., None], -1)[..., 0]
    p0 = np.take_along_axis(prof, (idx - 1)[..., None], -1)[..., 0]
    frac = (level - p0) / np.where(p1 - p0 == 0, 1.0, p1 - p0)
    s_star = (s_unit[idx - 1] + frac * (s_unit[1] - s_unit[0])) * L[:, :, None]
    out = P + s_star[..., None] * nrm[:, :, None, :]
    out[~ok] = np.nan
    return out


def _fit_lines(pts: np.ndarray):
    """Total-least-squares lines through points (..., n, 2) (NaN = missing), with one pass
    of outlier rejection (4 MAD). Returns (point (..., 2), direction (..., 2), ok (...))."""
    valid = np.all(np.isfinite(pts), axis=-1)
    p = np.where(valid[..., None], pts, 0.0)
    for _ in range(2):
        cnt = valid.sum(axis=-1)
        w = valid[..., None].astype(float)
        m = (p * w).sum(axis=-2) / np.maximum(cnt, 1)[..., None]
        d = (p - m[..., None, :]) * w
        C = np.einsum("...ni,...nj->...ij", d, d)
        _, vec = np.linalg.eigh(C)
        dirn, nrm = vec[..., :, 1], vec[..., :, 0]
        r = np.abs(np.einsum("...ni,...i->...n", p - m[..., None, :], nrm))
        rv = np.where(valid, r, np.nan)
        with warnings.catch_warnings():  # a side with no edge point: all-NaN median
            warnings.simplefilter("ignore", RuntimeWarning)
            mad = np.nanmedian(rv, axis=-1) * 1.4826 + 1e-3
        valid = valid & (r <= 4 * mad[..., None])
    return m, dirn, valid.sum(axis=-1) >= 4


def corners_from_edges(edges: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Corners (M, 4, 2) as intersections of the fitted side lines (same pixel frame as
    ``edges`` (M, 4, n, 2)); corner k is where side k-1 meets side k. ``fallback`` corners
    are kept where a side cannot be fitted."""
    out = np.array(fallback, float, copy=True).reshape(-1, 4, 2)
    if len(out) == 0:
        return out
    m, d, ok = _fit_lines(np.asarray(edges, float))
    p0, d0, ok0 = np.roll(m, 1, axis=1), np.roll(d, 1, axis=1), np.roll(ok, 1, axis=1)
    det = d0[..., 0] * (-d[..., 1]) - (-d[..., 0]) * d0[..., 1]
    rhs = m - p0
    with np.errstate(all="ignore"):
        s0 = (rhs[..., 0] * (-d[..., 1]) - (-d[..., 0]) * rhs[..., 1]) / det
    x = p0 + s0[..., None] * d0
    good = ok & ok0 & (np.abs(det) > 1e-6) & np.all(np.isfinite(x), axis=-1)
    good &= np.hypot(*(x - out).transpose(2, 0, 1)) < 3.0
    out[good] = x[good]
    return out
