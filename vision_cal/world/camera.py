"""Pinhole cameras looking at the sheet, projection, and lens distortion of a render.

Conventions
-----------
- OpenCV camera frame: x right, y down, z forward (along the optical axis), mm.
- Sheet points are (x, y, 0) in the sheet frame S (x right, y up, z up out of the paper
  towards the camera). ``T_cam_sheet`` (4, 4) maps homogeneous sheet points to the camera
  frame: ``p_cam = T_cam_sheet @ [x, y, z, 1]``.
- Pixels: OpenCV convention, (u, v) = (col, row) with integer values at pixel centres, so the
  image centre of a w x h image is ((w-1)/2, (h-1)/2).
- ``dist``: OpenCV coefficients k1 k2 p1 p2 [k3 ...]; ``None`` means none.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np
from scipy.interpolate import RectBivariateSpline
from scipy.ndimage import map_coordinates

from vision_cal.errors import VisionCalError

_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
#: sizes (px at the image corner, per 1000 px of image half-diagonal) of the lens terms
#: beyond k1 k2 in a real photo (world/photo's module docstring: 0.2 px each at the corner
#: of the 400 px half-diagonal of fixtures/real_charuco_opencv, 0.5 per 1000 px, rounded up)
PHONE_TANGENTIAL_PX = 0.6
PHONE_PRISM_PX = 0.6


def camera_matrix(*, size_px, f_px: float, principal_px=None) -> np.ndarray:
    """K (3, 3) with square pixels; the principal point at ``principal_px`` (u, v), by
    default the image centre ((w - 1) / 2, (h - 1) / 2)."""
    w, h = (float(v) for v in size_px)
    cx, cy = ((w - 1) / 2, (h - 1) / 2) if principal_px is None else (
        float(principal_px[0]), float(principal_px[1]))
    return np.array([[f_px, 0.0, cx], [0.0, f_px, cy], [0.0, 0.0, 1.0]])


def look_at(*, eye_mm, target_mm, up_hint=(0.0, 1.0, 0.0)) -> np.ndarray:
    """T_cam_sheet (4, 4) of a camera at ``eye_mm`` looking at ``target_mm`` (sheet frame).

    ``up_hint`` (sheet frame) is the direction that appears upwards in the image (as far as
    it is perpendicular to the view direction). ``target_mm`` may be (x, y) on the paper.
    """
    eye = np.asarray(eye_mm, dtype=float).reshape(3)
    tgt = np.asarray(target_mm, dtype=float).ravel()
    tgt = np.append(tgt, 0.0) if tgt.size == 2 else tgt.reshape(3)
    z = tgt - eye
    if np.linalg.norm(z) == 0:
        raise VisionCalError("eye and target coincide", field="eye_mm")
    z = z / np.linalg.norm(z)
    up = np.asarray(up_hint, dtype=float).reshape(3)
    y = -(up - np.dot(up, z) * z)
    if np.linalg.norm(y) < 1e-9:
        raise VisionCalError("up_hint is parallel to the view direction", field="up_hint")
    y = y / np.linalg.norm(y)
    x = np.cross(y, z)
    R = np.stack([x, y, z])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = -R @ eye
    return T


def project(xy_mm, *, K, dist=None, T_cam_sheet) -> np.ndarray:
    """Pixels (N, 2) of sheet points ``xy_mm`` (N, 2) (or (N, 3) with z) via cv2.projectPoints."""
    pts = np.asarray(xy_mm, dtype=float)
    pts = pts.reshape(-1, pts.shape[-1]) if pts.size else np.zeros((0, 2))
    if pts.shape[1] == 2:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    if len(pts) == 0:
        return np.zeros((0, 2))
    T = np.asarray(T_cam_sheet, dtype=float)
    rvec, _ = cv2.Rodrigues(T[:3, :3])
    d = np.zeros(5) if dist is None else np.asarray(dist, dtype=float).ravel()
    uv, _ = cv2.projectPoints(pts, rvec, T[:3, 3].copy(), np.asarray(K, dtype=float), d)
    return uv.reshape(-1, 2)


def default_views(sheet, *, n: int, size_px, K, tilt_deg=(0.0, 25.0), rng=None,
                  fill=0.92, roll_deg=5.0, target_jitter=0.05) -> list[np.ndarray]:
    """``n`` random views from above that keep the whole sheet in frame.

    Each view looks at a point near the sheet centre (jittered by ``target_jitter`` of the
    sheet size) from a direction tilted ``tilt_deg`` (uniform in the range) off the vertical
    at a random azimuth, with a random roll up to +-``roll_deg`` and the sheet's y axis
    roughly up in the image; the distance is the smallest one at which all four paper
    corners lie inside the central ``fill`` fraction of the image.
    """
    rng = np.random.default_rng(rng)
    x0, y0, x1, y1 = (float(v) for v in sheet.extent_mm)
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    w, h = (float(v) for v in size_px)
    K = np.asarray(K, dtype=float)
    half = np.array([w, h]) * (1 - fill) / 2
    lo_px, hi_px = half - 0.5, np.array([w, h]) - 0.5 - half
    size = np.array([x1 - x0, y1 - y0])
    views = []
    for _ in range(int(n)):
        tilt = np.radians(rng.uniform(*tilt_deg))
        az = rng.uniform(0, 2 * np.pi)
        roll = np.radians(rng.uniform(-roll_deg, roll_deg))
        target = np.array([(x0 + x1) / 2, (y0 + y1) / 2]) + rng.uniform(-1, 1, 2) * target_jitter * size
        direction = np.array([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
        up = np.array([-np.sin(roll), np.cos(roll), 0.0])

        def pose(dist_mm):
            eye = np.append(target, 0.0) + dist_mm * direction
            return look_at(eye_mm=eye, target_mm=target, up_hint=up)

        def fits(dist_mm):
            T = pose(dist_mm)
            pc = (T[:3, :3] @ np.column_stack([corners, np.zeros(4)]).T).T + T[:3, 3]
            if np.any(pc[:, 2] <= 0):
                return False
            uv = project(corners, K=K, T_cam_sheet=T)
            return bool(np.all(uv >= lo_px) and np.all(uv <= hi_px))

        lo, hi = 1.0, 10.0 * float(np.hypot(*size)) * K[0, 0] / min(w, h) + 1.0
        while not fits(hi):
            hi *= 2
            if hi > 1e9:
                raise VisionCalError("cannot fit the sheet in the image", field="tilt_deg")
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if fits(mid) else (mid, hi)
        views.append(pose(hi))
    return views


_MAP_STEP_PX = 8   # exact undistortPoints on this grid, bicubic spline in between


@functools.lru_cache(maxsize=8)
def _undistort_maps(size_px: tuple[int, int], K_key: bytes, dist_key: bytes, P_key: bytes):
    """float32 maps (h, w): where each distorted pixel looks in the ideal image.

    cv2.undistortPoints (iterated to 1e-12) on a grid every ``_MAP_STEP_PX`` pixels
    (reaching past the border), interpolated by a bicubic spline: off the exact per-pixel
    result by 1e-4 px (the float32 storage), 30x faster on a 4000 x 3000 image.
    """
    w, h = size_px
    K = np.frombuffer(K_key).reshape(3, 3)
    P = np.frombuffer(P_key).reshape(3, 3)
    dist = np.frombuffer(dist_key)
    st = _MAP_STEP_PX
    us = np.arange(-2 * st, w + 3 * st, st, dtype=np.float64)
    vs = np.arange(-2 * st, h + 3 * st, st, dtype=np.float64)
    U, V = np.meshgrid(us, vs)
    pd = np.stack([U.ravel(), V.ravel()], axis=-1).reshape(-1, 1, 2)
    pu = cv2.undistortPoints(pd, K, dist, P=P, criteria=_UNDISTORT_CRITERIA)
    pu = pu.reshape(len(vs), len(us), 2)
    rows, cols = np.arange(h, dtype=np.float64), np.arange(w, dtype=np.float64)
    maps = []
    for k in range(2):
        spline = RectBivariateSpline(vs, us, pu[..., k], kx=3, ky=3, s=0)
        maps.append(spline(rows, cols).astype(np.float32))
    return maps[0], maps[1]


_CV2_INTERPOLATION = {"linear": cv2.INTER_LINEAR, "cubic": cv2.INTER_CUBIC,
                      "lanczos4": cv2.INTER_LANCZOS4}


def ideal_K(size_px, K, dist) -> np.ndarray:
    """K (3, 3) of the ideal pinhole render a lens ``(K, dist)`` needs to fill the whole
    photo of ``size_px``: ``K`` itself, except for a lens that pulls the corners in
    (barrel): then a shorter focal length (same principal point) wide enough to hold every
    undistorted photo corner, which ``Photographer.photograph(K_dist=K, dist=...)`` maps
    back (without it the photo's corners come out black, and markers cut by the black
    are found with corners pixels off)."""
    K = np.asarray(K, dtype=float)
    if dist is None or not any(dist):
        return K
    w, h = size_px
    border = np.concatenate([
        np.column_stack([np.linspace(0, w - 1, 33), np.zeros(33)]),
        np.column_stack([np.linspace(0, w - 1, 33), np.full(33, h - 1.0)]),
        np.column_stack([np.zeros(25), np.linspace(0, h - 1, 25)]),
        np.column_stack([np.full(25, w - 1.0), np.linspace(0, h - 1, 25)])])
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    xn = cv2.undistortPoints(border.reshape(-1, 1, 2), K, np.asarray(dist, float),
                             criteria=crit).reshape(-1, 2)
    c = K[:2, 2]
    # the ideal render (focal f') must hold f' * xn + c inside [-0.5, size - 0.5]
    need = np.max(np.abs(xn) / np.maximum(np.abs(np.column_stack([
        np.where(xn[:, 0] < 0, c[0] + 0.5, w - 0.5 - c[0]),
        np.where(xn[:, 1] < 0, c[1] + 0.5, h - 0.5 - c[1])])), 1e-9), axis=0).max()
    f_ideal = min(K[0, 0], 0.995 / need)
    Ki = K.copy()
    Ki[0, 0] = Ki[1, 1] = f_ideal
    return Ki


def distort_image(img, *, K, dist, K_ideal=None, interpolation: str = "spline3",
                  border_value=0) -> np.ndarray:
    """The photo a lens with ``(K, dist)`` takes, from an ideal pinhole render ``img``.

    ``img`` (h, w) or (h, w, c) was rendered with camera matrix ``K_ideal`` (default ``K``)
    and no distortion. Every output pixel p_d looks up the ideal image at
    ``p_u = cv2.undistortPoints(p_d, K, dist, P=K_ideal)`` (iterated to 1e-12), so a sheet
    point lands where ``cv2.projectPoints(..., K, dist)`` puts it.

    ``interpolation``: ``"spline3"`` (default) is a cubic B-spline interpolation
    (``scipy.ndimage.map_coordinates``) at the exact positions. ``"linear"``, ``"cubic"``,
    ``"lanczos4"`` use cv2.remap, ~10x faster but it quantises positions to 1/32 px (fine on
    a supersampled image that is then averaged down; ``bench/render.py --accuracy`` prints
    the resulting dot-centre figures).
    Outside the ideal frame the output is ``border_value``. The maps are cached per
    (size, K, dist, K_ideal).
    """
    img = np.asarray(img)
    if dist is None or not np.any(np.asarray(dist, dtype=float)):
        if K_ideal is None or np.allclose(K_ideal, K):
            return img.copy()
    h, w = img.shape[:2]
    K = np.ascontiguousarray(K, dtype=np.float64)
    P = K if K_ideal is None else np.ascontiguousarray(K_ideal, dtype=np.float64)
    d = np.zeros(5) if dist is None else np.ascontiguousarray(np.ravel(dist), dtype=np.float64)
    mx, my = _undistort_maps((w, h), K.tobytes(), d.tobytes(), P.tobytes())
    if interpolation in _CV2_INTERPOLATION:
        return cv2.remap(img, mx, my, _CV2_INTERPOLATION[interpolation],
                         borderMode=cv2.BORDER_CONSTANT, borderValue=border_value)
    if interpolation != "spline3":
        raise VisionCalError(f"unknown interpolation {interpolation!r}", field="interpolation")
    coords = np.stack([my, mx])
    planes = img[..., None] if img.ndim == 2 else img
    out = np.empty(planes.shape, dtype=img.dtype)
    for c in range(planes.shape[2]):
        v = map_coordinates(planes[..., c].astype(np.float32), coords, order=3,
                            mode="grid-constant", cval=float(border_value), prefilter=True)
        if np.issubdtype(img.dtype, np.integer):
            info = np.iinfo(img.dtype)
            v = np.clip(np.rint(v), info.min, info.max)
        out[..., c] = v
    return out[..., 0] if img.ndim == 2 else out


def phone_lens(*, f_px: float, size_px, k1: float = 0.0, k2: float = 0.0,
               tangential_px: float | None = None, prism_px: float | None = None,
               rng=None) -> tuple[float, ...]:
    """OpenCV's 12 lens coefficients (k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4): radial ``k1``
    ``k2`` and tangential and thin-prism terms that move the image corner by
    ``tangential_px`` and ``prism_px`` pixels each (default: ``PHONE_TANGENTIAL_PX`` and
    ``PHONE_PRISM_PX`` per 1000 px of the image's half-diagonal), in directions drawn
    from ``rng`` (a seed or a Generator)."""
    rng = np.random.default_rng(rng)
    half = float(np.hypot(*size_px)) / 2.0
    tangential_px = PHONE_TANGENTIAL_PX * half / 1000.0 if tangential_px is None else tangential_px
    prism_px = PHONE_PRISM_PX * half / 1000.0 if prism_px is None else prism_px
    # the corner of an image of aspect w:h, in normalised units; each family's shape is drawn
    # at random, then scaled so that its largest shift over the four corners is the size
    x, y = size_px[0] / 2.0 / float(f_px), size_px[1] / 2.0 / float(f_px)
    a = rng.uniform(0, 2 * np.pi)
    p = np.array([np.cos(a), np.sin(a)])
    s = rng.standard_normal(4)
    d_t = corner_shift((0, 0, p[0], p[1], 0, 0, 0, 0, 0, 0, 0, 0), x, y)
    d_s = corner_shift((0, 0, 0, 0, 0, 0, 0, 0, *s), x, y)
    p = p * (tangential_px / f_px / max(d_t, 1e-12))
    s = s * (prism_px / f_px / max(d_s, 1e-12))
    return (float(k1), float(k2), float(p[0]), float(p[1]), 0.0, 0.0, 0.0, 0.0,
            *(float(v) for v in s))


def corner_shift(dist, x: float, y: float) -> float:
    """Largest shift (normalised units) the non-radial ``dist`` terms give over the four
    image corners (+-x, +-y)."""
    out = 0.0
    for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        P = np.array([[sx * x, sy * y, 1.0]])
        q, _ = cv2.projectPoints(P, np.zeros(3), np.zeros(3), np.eye(3), np.asarray(dist, float))
        out = max(out, float(np.hypot(*(q.ravel() - P[0, :2]))))
    return out
