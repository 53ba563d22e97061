"""Photos of one camera stored turned by a quarter (a phone held upright): one lens.

A phone writes some photos as ``W x H`` pixels and others, taken upright, as ``H x W`` (the
pixels turned, or an EXIF orientation the decoder applied). Those are the same sensor and
lens: the intrinsics turn with the pixels. :func:`to_main_px` maps a turned photo's pixels
into the main frame (``turn`` +1: the main frame is the turned photo rotated 90 degrees
clockwise, -1: counter-clockwise), so that :func:`vision_cal.measure.mapping.estimate_lens`
fits one lens over all photos; :func:`turned_lens` gives that lens in the turned photo's
own pixels (K and the tangential terms turned; radial terms unchanged). Which way a set of
photos is turned is taken from the fit: the direction whose joint lens fits the marker
corners better (the principal point and tangential terms tell them apart).
"""

from __future__ import annotations

import numpy as np


def transposed(a, b) -> bool:
    """Whether image sizes ``a`` and ``b`` (w, h) are a quarter turn of each other."""
    return a is not None and b is not None and tuple(a) == (b[1], b[0]) and a[0] != a[1]


def to_main_px(uv_px, main_size, turn: int) -> np.ndarray:
    """Pixels (..., 2) of a photo turned against ``main_size`` (W, H) into the main frame."""
    uv = np.asarray(uv_px, float)
    W, H = main_size
    u, v = uv[..., 0], uv[..., 1]
    if turn == 1:     # main = turned photo rotated clockwise: (u, v) -> (H_r - 1 - v, u)
        out = np.stack([W - 1 - v, u], axis=-1)
    elif turn == -1:  # counter-clockwise: (u, v) -> (v, W_r - 1 - u)
        out = np.stack([v, H - 1 - u], axis=-1)
    else:
        raise ValueError(f"turn must be +1 or -1, got {turn!r}")
    return out


def turned_lens(K, dist, main_size, turn: int) -> tuple[np.ndarray, np.ndarray]:
    """The main frame's lens (K (3, 3), dist k1 k2 p1 p2 k3) in a turned photo's pixels."""
    K = np.asarray(K, float)
    d = np.zeros(5)
    d[:len(np.ravel(dist))] = np.ravel(dist)[:5]
    W, H = main_size
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    k1, k2, p1, p2, k3 = d
    if turn == 1:     # turned px: u_r = v_m, v_r = W - 1 - u_m; x_r = y_m, y_r = -x_m
        Kr = np.array([[fy, 0.0, cy], [0.0, fx, W - 1 - cx], [0.0, 0.0, 1.0]])
        dr = np.array([k1, k2, -p2, p1, k3])
    elif turn == -1:  # u_r = H - 1 - v_m, v_r = u_m; x_r = -y_m, y_r = x_m
        Kr = np.array([[fy, 0.0, H - 1 - cy], [0.0, fx, cx], [0.0, 0.0, 1.0]])
        dr = np.array([k1, k2, p2, -p1, k3])
    else:
        raise ValueError(f"turn must be +1 or -1, got {turn!r}")
    return Kr, dr
