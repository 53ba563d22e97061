"""Do the markers seen in a photo fit the sheet that ``session.json`` declares?

The mapping of a photo is a homography fitted to every marker corner; what it cannot fit
is the marker-corner residual (``SheetMapping.corner_rms_mm``). A real printer scales the
page (by up to about 1 %, unevenly in x and y): that is an affine map, which a homography
absorbs whole, so it leaves nothing. What it can leave is a marker printed off its own
declared size, at most that scale over the marker's side; and a lens nobody declared, or
one estimated a little wrong, leaves a pixel or more at the corners (measured on hand-held
phone series, ``bench/phone.py --gate``). So the tolerance is

    tol_mm = PRINT_SCALE * marker side + LENS_PX * mm per pixel

(0.3 + 1.2 mm for 30 mm markers photographed at 0.6 mm per pixel). Typing the sheet
wrong leaves far more: corners listed in reverse order leave about the marker's side
(30 mm), markers declared 27 mm when printed 30 mm about 2 mm. A photo beyond the tolerance
is not measured, and :func:`likely_cause` says why in words a user can act on.
"""

from __future__ import annotations

import itertools

import cv2
import numpy as np

from vision_cal.config import DEFAULT, SheetFitConfig

MISFIT = "markers do not fit the declared sheet"

#: corner orders a user may have typed instead of TL, TR, BR, BL (indices into the declared)
_ORDER_NAMES = ("top-left", "top-right", "bottom-right", "bottom-left")


def marker_side_mm(corners_mm) -> float:
    """Median side (mm) of the declared markers (M, 4, 2)."""
    c = np.asarray(corners_mm, float).reshape(-1, 4, 2)
    sides = np.linalg.norm(c - np.roll(c, -1, axis=1), axis=2)
    return float(np.median(sides))


def corner_tolerance_mm(corners_mm, mm_per_px: float,
                        config: SheetFitConfig | None = None) -> float:
    """Largest marker-corner RMS (mm) a printer and a lens can explain (module docstring;
    the two terms: ``config``, default ``vision_cal.config.DEFAULT.sheet_fit``)."""
    cfg = config or DEFAULT.sheet_fit
    return cfg.print_scale * marker_side_mm(corners_mm) + cfg.lens_px * float(mm_per_px)


def _rms_mm(corners_mm: np.ndarray, corners_px: np.ndarray) -> float:
    """RMS (mm) of the corners mapped by the homography fitted px -> mm."""
    mm = corners_mm.reshape(-1, 2)
    px = corners_px.reshape(-1, 2)
    G, _ = cv2.findHomography(px, mm, 0)
    if G is None or not np.all(np.isfinite(G)):
        return float("inf")
    p = np.c_[px, np.ones(len(px))] @ G.T
    r = p[:, :2] / p[:, 2:3] - mm
    return float(np.sqrt(np.mean(np.sum(r**2, axis=1))))


def likely_cause(corners_mm, corners_px, tol_mm: float,
                 config: SheetFitConfig | None = None) -> str:
    """Which typing mistake in ``sheet.markers`` explains the misfit (one phrase).

    Tried in turn: the four corners listed in another order (reversed, or starting at
    another corner), every marker printed at another size than declared (fitted from the
    marker centres alone, which do not depend on the size), else markers that are not where
    the sheet puts them (other ids, another dictionary or layout)."""
    mm = np.asarray(corners_mm, float).reshape(-1, 4, 2)
    px = np.asarray(corners_px, float).reshape(-1, 4, 2)
    if len(mm) < 2:
        return "too few markers to tell"
    best = None
    for start, rev in itertools.product(range(4), (False, True)):
        order = [(start + (-k if rev else k)) % 4 for k in range(4)]
        if order == [0, 1, 2, 3]:
            continue
        rms = _rms_mm(mm[:, order], px)
        if best is None or rms < best[0]:
            best = (rms, order)
    if best is not None and best[0] <= tol_mm:
        # detected corner k (in TL, TR, BR, BL order) matches declared corner order[k]
        listed = [""] * 4
        for k, j in enumerate(best[1]):
            listed[j] = _ORDER_NAMES[k]
        return ("corner order: corners_mm look listed as " + ", ".join(listed) +
                " (expected top-left, top-right, bottom-right, bottom-left of the upright "
                "marker)")
    centres_mm = mm.mean(axis=1)
    if len(mm) >= 4:
        G, _ = cv2.findHomography(px.mean(axis=1), centres_mm, 0)
        if G is not None and np.all(np.isfinite(G)):
            p = np.c_[px.reshape(-1, 2), np.ones(px.size // 2)] @ G.T
            seen = (p[:, :2] / p[:, 2:3]).reshape(-1, 4, 2)
            ratio = marker_side_mm(seen) / max(marker_side_mm(mm), 1e-9)
            rescaled = centres_mm[:, None] + (mm - centres_mm[:, None]) * ratio
            if abs(ratio - 1) > (config or DEFAULT.sheet_fit).print_scale and _rms_mm(rescaled, px) <= tol_mm:
                return (f"marker size: printed about {marker_side_mm(seen):.1f} mm, declared "
                        f"{marker_side_mm(mm):.1f} mm")
    return ("markers not where sheet.markers puts them (other ids, another dictionary or "
            "layout than the printed sheet)")


#: the phrase of a misfit the declared lens explains (the field to fix is camera.dist)
LENS_CAUSE = "camera.dist"


def misfit_reason(corners_mm, corners_px, rms_mm: float, tol_mm: float, *,
                  raw_px=None, config: SheetFitConfig | None = None) -> str:
    """The one-line reason a photo is not measured (starts with :data:`MISFIT`).
    ``raw_px``: the corners without the declared lens distortion (when one is declared):
    if they fit the sheet (within the tolerance, or twice as well), the declared
    ``camera.dist`` is the likely cause, not the sheet."""
    cause = None
    if raw_px is not None:
        raw = _rms_mm(np.asarray(corners_mm, float), np.asarray(raw_px, float))
        if raw <= tol_mm or raw < 0.5 * rms_mm:
            cause = (f"{LENS_CAUSE}: the declared lens distortion is wrong (without it the "
                     f"markers fit to {raw:.3g} mm)")
    if cause is None:
        cause = likely_cause(corners_mm, corners_px, tol_mm, config)
    return (f"{MISFIT}: corner RMS {rms_mm:.3g} mm, a printer and lens explain "
            f"{tol_mm:.2g} mm; likely cause: {cause}")
