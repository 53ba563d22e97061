"""Reading a rasterised sheet back, independently of the writers: ArUco corners and the
scale bars, in sheet mm.

Raster convention (pdfium, and the sheet PNG): pixel (row i, col j) covers
[j, j+1) x [i, i+1) device pixels; row 0 is the top of the page. So an OpenCV pixel
coordinate (u, v) (integer at pixel centres) is the sheet point
``x = x_min + (u + 0.5) / ppm``, ``y = y_max - (v + 0.5) / ppm``.
"""

from __future__ import annotations

import cv2
import numpy as np

ANNOT_MIN_BLUE = 60   # blue minus red of the bars' ink (70, 120, 200) over white paper


def px_to_mm(uv, extent_mm, ppm):
    """OpenCV pixel coordinates (N, 2) -> sheet mm; ``ppm`` a number or (ppm_x, ppm_y)."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    px, py = np.broadcast_to(np.asarray(ppm, float), (2,))
    x0, _, _, y1 = extent_mm
    return np.column_stack([x0 + (uv[:, 0] + 0.5) / px, y1 - (uv[:, 1] + 0.5) / py])


def rasterise_pdf(path, ppm: float):
    """Page 1 by pdfium (not the writer) at about ``ppm`` pixels per mm.

    Returns (RGB (H, W, 3) uint8, (ppm_x, ppm_y)): pdfium stretches the page over a whole
    number of pixels, so the scale actually used is the bitmap's size over the page's.
    """
    import pypdfium2 as pdfium

    pdf = pdfium.PdfDocument(str(path))
    try:
        page = pdf[0]
        w_pt, h_pt = page.get_size()
        bm = page.render(scale=ppm * 25.4 / 72.0, rev_byteorder=True)
        rgb = np.ascontiguousarray(bm.to_numpy()[:, :, :3])
    finally:
        pdf.close()
    H, W = rgb.shape[:2]
    return rgb, (W / (w_pt * 25.4 / 72.0), H / (h_pt * 25.4 / 72.0))


def rasterise_mupdf(path, ppm: float):
    """Page 1 by MuPDF (``pymupdf``, a test dependency: neither the writer nor pdfium) at
    ``ppm`` px/mm. MuPDF keeps the exact scale and rounds the bitmap out to whole pixels
    (the last row or column may be partly off the page). Returns (RGB, (ppm, ppm))."""
    import pymupdf

    doc = pymupdf.open(str(path))
    try:
        s = ppm * 25.4 / 72.0
        pix = doc[0].get_pixmap(matrix=pymupdf.Matrix(s, s), alpha=False,
                                colorspace=pymupdf.csRGB)
        rgb = np.frombuffer(pix.samples, np.uint8).reshape(pix.height, pix.width, 3).copy()
    finally:
        doc.close()
    return rgb, (float(ppm), float(ppm))


#: a system tool a test uses, absent: what to install (the README's "Tests and the tools
#: they use" lists the same); under CI (CI=true) a failure, not a skip: .ci/run installs it
SYSTEM_TOOLS = {
    "pdftoppm": "poppler's pdftoppm is not installed: install poppler-utils (Debian/Ubuntu: "
                "sudo apt-get install poppler-utils; Fedora: sudo dnf install poppler-utils; "
                "macOS: brew install poppler) so that `pdftoppm` is on PATH",
}


def require_tool(name: str) -> str:
    """The path of system tool ``name``; absent, the test skips saying what to install
    (fails under CI, whose .ci/run installs it)."""
    import os
    import shutil

    import pytest

    exe = shutil.which(name)
    if exe is None:
        msg = SYSTEM_TOOLS[name]
        if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
            pytest.fail(msg + "; CI must install it (.ci/run)")
        pytest.skip(msg + ", then make test runs this check")
    return exe


def rasterise_pdftoppm(path, ppm: float):
    """Page 1 by poppler's ``pdftoppm`` at ``ppm`` px/mm (a system tool: a test skips
    without it, :func:`require_tool`). Poppler keeps the exact scale (the last pixel row or
    column may be partly off the page). Returns (RGB, (ppm, ppm))."""
    import subprocess
    import tempfile

    from PIL import Image

    exe = require_tool("pdftoppm")
    with tempfile.TemporaryDirectory() as d:
        subprocess.run([exe, "-r", f"{ppm * 25.4:.6f}", "-singlefile", str(path),
                        f"{d}/p"], check=True, capture_output=True)
        with Image.open(f"{d}/p.ppm") as im:      # raw PPM: no PNG encoding
            rgb = np.asarray(im.convert("RGB"))
    return rgb, (float(ppm), float(ppm))


def detect_corners_mm(rgb: np.ndarray, dictionary: str, extent_mm, ppm: float) -> dict:
    """id -> (4, 2) corners in sheet mm (TL, TR, BR, BL), cv2.aruco + cornerSubPix."""
    gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    p = cv2.aruco.DetectorParameters()
    p.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_NONE
    corners, ids, _ = cv2.aruco.ArucoDetector(d, p).detectMarkers(gray)
    if ids is None:
        return {}
    ids = np.asarray(ids).reshape(-1)
    c = np.asarray(corners, np.float32).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-4)
    # well inside a module: the window sees one corner only
    win = max(3, int(0.6 * float(np.min(ppm))))
    c = cv2.cornerSubPix(gray, c, (win, win), (-1, -1), crit)
    c = np.asarray(c, float).reshape(len(ids), 4, 2)
    return {int(i): px_to_mm(cc, extent_mm, ppm) for i, cc in zip(ids, c)}


def find_bars_mm(rgb: np.ndarray, extent_mm, ppm) -> dict:
    """The two scale bars found as the long thin blue components of the raster.

    Returns {"x": (start_mm (2,), end_mm (2,)), "y": ...}: each end from the bar's ink
    coverage summed along rows (columns) through its middle, i.e. exact area, then placed
    from the first partly covered pixel.
    """
    r, g, b = (rgb[..., k].astype(float) for k in range(3))
    blue = ((b - r) > ANNOT_MIN_BLUE).astype(np.uint8)
    n, lab, st, _ = cv2.connectedComponentsWithStats(blue, connectivity=8)
    cov = np.clip((255.0 - r) / (255.0 - 70.0), 0.0, 1.0)   # ink coverage of the bar colour
    out = {}
    ppm_x, ppm_y = np.broadcast_to(np.asarray(ppm, float), (2,))
    for k in range(1, n):
        x, y, w, h = st[k, :4]
        long_, thin = max(w, h), min(w, h)
        if long_ < 80 * min(ppm_x, ppm_y) or thin > 3 * max(ppm_x, ppm_y):
            continue
        axis = "x" if w > h else "y"
        if axis == "x":
            rows = slice(y + h // 2 - h // 4, y + h // 2 + h // 4 + 1)
            band = cov[rows, max(x - 3, 0):x + w + 3]
            length_px = band.sum(axis=1).mean()
            first = np.argmax(band.mean(axis=0) > 1e-3) + max(x - 3, 0)
            start_u = first + 1 - band.mean(axis=0)[first - max(x - 3, 0)] - 0.5
            start = px_to_mm([[start_u, y + h / 2 - 0.5]], extent_mm, ppm)[0]
            end = start + [length_px / ppm_x, 0.0]
        else:
            cols = slice(x + w // 2 - w // 4, x + w // 2 + w // 4 + 1)
            band = cov[max(y - 3, 0):y + h + 3, cols]
            length_px = band.sum(axis=0).mean()
            prof = band.mean(axis=1)
            last = len(prof) - 1 - np.argmax(prof[::-1] > 1e-3)   # bottom end (lowest y)
            bottom_v = last + max(y - 3, 0) + prof[last] - 0.5
            start = px_to_mm([[x + w / 2 - 0.5, bottom_v]], extent_mm, ppm)[0]
            end = start + [0.0, length_px / ppm_y]
        out[axis] = (start, end)
    return out
