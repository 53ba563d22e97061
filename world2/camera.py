"""World2's camera: a pinhole with Brown-Conrady distortion, and photographs by ray casting.

Each image pixel (or ``ss x ss`` samples of it) has its ray undistorted (own fixed-point
inversion of the distortion, on a 4 px lattice, interpolated), cast onto the paper (whose
height varies), and the scene is asked what reflectance lies there, box-filtered over the
sample's footprint on the paper (lines and ink analytically, the markers' textures
pre-blurred). The samples are averaged per pixel, blurred by the lens, lit unevenly,
gamma-encoded, given sensor noise and quantised.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class Lens:
    K: np.ndarray            # (3, 3)
    dist: np.ndarray         # (5,) k1, k2, p1, p2, k3
    size_px: tuple[int, int]  # w, h

    def distort(self, xn: np.ndarray, yn: np.ndarray):
        k1, k2, p1, p2, k3 = self.dist
        r2 = xn * xn + yn * yn
        rad = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = xn * rad + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn * xn)
        yd = yn * rad + p1 * (r2 + 2 * yn * yn) + 2 * p2 * xn * yn
        return xd, yd

    def undistort(self, u: np.ndarray, v: np.ndarray, iters: int = 7):
        """Normalised ray coordinates (x, y) of pixels (u, v)."""
        K = self.K
        yd = (v - K[1, 2]) / K[1, 1]
        xd = (u - K[0, 2] - K[0, 1] * yd) / K[0, 0]
        x, y = xd.copy(), yd.copy()
        k1, k2, p1, p2, k3 = self.dist
        for _ in range(iters):
            r2 = x * x + y * y
            rad = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
            dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
            dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
            x = (xd - dx) / rad
            y = (yd - dy) / rad
        return x, y

    def project(self, T_cam_sheet: np.ndarray, P: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of sheet points P (N, 3)."""
        c = P @ T_cam_sheet[:3, :3].T + T_cam_sheet[:3, 3]
        xd, yd = self.distort(c[:, 0] / c[:, 2], c[:, 1] / c[:, 2])
        K = self.K
        return np.column_stack([K[0, 0] * xd + K[0, 1] * yd + K[0, 2], K[1, 1] * yd + K[1, 2]])


def look_at(eye: np.ndarray, target: np.ndarray, roll_deg: float) -> np.ndarray:
    """T_cam_sheet of a camera at ``eye`` looking at ``target``; image x near sheet x turned
    by ``roll_deg``, image y down (sheet y up)."""
    z = target - eye
    z = z / np.linalg.norm(z)
    hint = np.array([np.cos(np.radians(roll_deg)), np.sin(np.radians(roll_deg)), 0.0])
    y = np.cross(z, hint)
    y /= np.linalg.norm(y)
    x = np.cross(y, z)
    R = np.vstack([x, y, z])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = -R @ eye
    return T


def view_from(lens: Lens, corners_xy: np.ndarray, centre: np.ndarray, tilt_deg: float,
              azimuth_deg: float, roll_deg: float, fill: float = 0.9) -> np.ndarray:
    """A pose seeing the paper's corners filling ``fill`` of the frame, tilted by
    ``tilt_deg`` from straight down, from the side ``azimuth_deg``."""
    t, a = np.radians(tilt_deg), np.radians(azimuth_deg)
    direction = np.array([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.cos(t)])
    P = np.column_stack([corners_xy, np.zeros(len(corners_xy))])
    dist = 1000.0
    w, h = lens.size_px
    for _ in range(30):
        T = look_at(centre + dist * direction, centre, roll_deg)
        uv = lens.project(T, P)
        half = np.max(np.abs(uv - [w / 2, h / 2]) / [w / 2, h / 2])
        dist *= half / fill
        if abs(half / fill - 1) < 1e-4:
            break
    return T


def photograph(lens: Lens, T_cam_sheet: np.ndarray, scene, *, ss: int, blur_px: float,
               noise: float, rng: np.random.Generator, light: np.ndarray,
               rows_per_chunk: int = 96, gamma: float = 2.2) -> np.ndarray:
    """An 8-bit BGR photo of ``scene`` (``intersect(eye, rays) -> x, y`` on the paper,
    ``reflectance(x, y, footprint_mm) -> (H, W, 3)``); ``light``: exposure, its gradient
    across the frame in x and y, vignetting."""
    w, h = lens.size_px
    R = T_cam_sheet[:3, :3]
    eye = -R.T @ T_cam_sheet[:3, 3]
    out = np.zeros((h, w, 3), np.float32)
    sub = (np.arange(ss) + 0.5) / ss - 0.5
    us = (np.arange(w)[:, None] + sub[None, :]).ravel()
    # rays on a 4 px lattice, interpolated per sample (the distortion is smooth)
    step = 4.0
    cu, cv = np.arange(-2, w + 6, step), np.arange(-2, h + 6, step)
    CU, CV = np.meshgrid(cu, cv)
    rx, ry = (a.astype(np.float32) for a in lens.undistort(CU, CV))
    for r0 in range(0, h, rows_per_chunk):
        r1 = min(h, r0 + rows_per_chunk)
        vs = (np.arange(r0, r1)[:, None] + sub[None, :]).ravel()
        U, V = np.meshgrid(((us - cu[0]) / step).astype(np.float32),
                           ((vs - cv[0]) / step).astype(np.float32))
        xn = cv2.remap(rx, U, V, cv2.INTER_LINEAR).astype(np.float64)
        yn = cv2.remap(ry, U, V, cv2.INTER_LINEAR).astype(np.float64)
        d = np.stack([xn, yn, np.ones_like(xn)], axis=-1) @ R      # rays in the sheet frame
        x, y = scene.intersect(eye, d)
        fp = float(np.median(np.hypot(np.diff(x, axis=1), np.diff(y, axis=1))))
        refl = scene.reflectance(x, y, fp)
        out[r0:r1] = cv2.resize(refl, (w, r1 - r0), interpolation=cv2.INTER_AREA)
    if blur_px > 0:
        out = cv2.GaussianBlur(out, (0, 0), blur_px)
    gy, gx = np.mgrid[0:h, 0:w].astype(np.float32)
    gx, gy = gx / w - 0.5, gy / h - 0.5
    illum = light[0] * (1 + light[1] * gx + light[2] * gy) * (1 - light[3] * (gx**2 + gy**2))
    lin = np.clip(out * illum[..., None], 0, 1)
    lin = lin + rng.normal(0, 1, lin.shape).astype(np.float32) * np.sqrt(noise**2 + 0.0004 * lin)
    srgb = np.clip(lin, 0, 1) ** (1 / gamma)
    return np.round(srgb[..., ::-1] * 255).astype(np.uint8)
