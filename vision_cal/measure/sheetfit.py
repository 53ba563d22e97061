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

Real paper and real phones leave more than that allowance (issue 28: a 3264 x 2448 phone
photo of a correctly described 60-marker sheet left 0.318 mm against 0.32 allowed; real
prints and phones leave 1.5-2.7 px). Before refusing, :func:`misfit_parts` splits the
misfit by what could cause it: the part a lens explains (k1 k2 p1 p2 about the image
centre, with the homography refitted), the part a smooth field over the sheet explains (a
printer's feed wave and bow, a paper not flat: a polynomial in the sheet's x y, of degree
3 to 7 with the markers seen), and what is
left. A photo whose leftover is within the allowance is measured (:func:`sheet_misfit`);
"markers not where sheet.markers puts them" is said only of a leftover no print, paper
or lens makes (a quarter of the marker side: other ids or another layout).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import cv2
import numpy as np

from vision_cal.config import DEFAULT, SheetFitConfig
from vision_cal.model.solve import solve

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
                 config: SheetFitConfig | None = None, parts: "MisfitParts | None" = None,
                 size_px=None) -> str:
    """Which typing mistake in ``sheet.markers`` explains the misfit (one phrase).

    Tried in turn: the four corners listed in another order (reversed, or starting at
    another corner), every marker printed at another size than declared (fitted from the
    marker centres alone, which do not depend on the size), then what :func:`misfit_parts`
    leaves: beyond ``wrong_place_side`` of the marker side, markers that are not where the
    sheet puts them (other ids, another dictionary or layout); else the print or the paper
    (``parts``: the split, computed when not given; ``size_px``: the photo's size, whose
    centre the lens terms turn about). The alternatives are judged by what they leave
    after the lens and the smooth field, so a lens nobody declared does not hide a typing
    mistake. A misfit that the lens terms alone take out (with a lens applied: a claim,
    :func:`sheet_misfit`) is blamed on ``camera.dist``."""
    mm = np.asarray(corners_mm, float).reshape(-1, 4, 2)
    px = np.asarray(corners_px, float).reshape(-1, 4, 2)
    if len(mm) < 2:
        return "too few markers to tell"
    best = None
    for start, rev in itertools.product(range(4), (False, True)):
        order = [(start + (-k if rev else k)) % 4 for k in range(4)]
        if order == [0, 1, 2, 3]:
            continue
        rms = misfit_parts(mm[:, order], px, size_px=size_px, config=config).left_mm
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
            if (abs(ratio - 1) > (config or DEFAULT.sheet_fit).print_scale
                    and misfit_parts(rescaled, px, size_px=size_px,
                                     config=config).left_mm <= tol_mm):
                return (f"marker size: printed about {marker_side_mm(seen):.1f} mm, declared "
                        f"{marker_side_mm(mm):.1f} mm")
    cfg = config or DEFAULT.sheet_fit
    parts = parts or misfit_parts(mm, px, size_px=size_px, config=cfg)
    side = marker_side_mm(mm)
    if parts.left_mm > cfg.wrong_place_side * side:
        return ("markers not where sheet.markers puts them (other ids, another dictionary or "
                f"layout than the printed sheet: {parts.left_mm:.2g} mm left after the lens "
                f"and a smooth print or paper field, {parts.left_mm / side:.0%} of the "
                "marker side)")
    if parts.left_mm > tol_mm:
        return (f"the print or the paper: {parts.left_mm:.2g} mm that neither a lens nor a "
                "smooth print or paper field explains (a fold or crease in the paper, a "
                "sheet not lying flat in patches, markers printed off the layout one by one)")
    if parts.smooth_mm <= cfg.smooth_max_mm:
        return (f"{LENS_CAUSE}: the lens applied is off (lens terms would still take out "
                f"{parts.lens_mm:.2g} mm)")
    return (f"the print or the paper: a smooth field of {parts.smooth_mm:.2g} mm over the "
            f"sheet (more than {cfg.smooth_max_mm:g} mm: the paper not flat, or printed "
            "off its layout), the lens explaining "
            f"{parts.lens_mm:.2g} mm")


#: the phrase of a misfit the declared lens explains (the field to fix is camera.dist)
LENS_CAUSE = "camera.dist"


def misfit_reason(corners_mm, corners_px, rms_mm: float, tol_mm: float, *,
                  raw_px=None, config: SheetFitConfig | None = None, size_px=None,
                  parts: "MisfitParts | None" = None) -> str:
    """The one-line reason a photo is not measured (starts with :data:`MISFIT`), with the
    sizes the lens, a smooth print or paper field and nothing explain (:func:`misfit_parts`).
    ``raw_px``: the corners without the declared lens distortion (when one is declared; a
    callable is called when needed): if they fit the sheet (within the tolerance, or twice
    as well), the declared ``camera.dist`` is the likely cause, not the sheet."""
    mm = np.asarray(corners_mm, float)
    px = np.asarray(corners_px, float)
    parts = parts or misfit_parts(mm, px, size_px=size_px, config=config)
    cause = None
    if raw_px is not None:
        raw = _rms_mm(mm, np.asarray(raw_px() if callable(raw_px) else raw_px, float))
        if raw <= tol_mm or raw < 0.5 * rms_mm:
            cause = (f"{LENS_CAUSE}: the declared lens distortion is wrong (without it the "
                     f"markers fit to {raw:.3g} mm)")
    if cause is None:
        cause = likely_cause(mm, px, tol_mm, config, parts, size_px)
    return (f"{MISFIT}: corner RMS {rms_mm:.3g} mm, a printer and lens explain "
            f"{tol_mm:.2g} mm ({parts.describe()}); likely cause: {cause}")


@dataclass(frozen=True)
class MisfitParts:
    """A photo's marker-corner misfit (RMS on the sheet, mm) split by what could cause it:
    ``total_mm`` after a homography; ``lens_mm`` the part lens terms explain (k1 k2 p1 p2
    about the image centre); ``smooth_mm`` the part a smooth field over the sheet explains
    (a polynomial in x y: a print's feed wave and bow, a paper not flat); ``left_mm`` what is
    left (detection noise, toner, a typing mistake). The parts add in quadrature."""

    total_mm: float
    lens_mm: float
    smooth_mm: float
    left_mm: float
    lens_fitted: bool
    smooth_fitted: bool

    def describe(self) -> str:
        lens = f"a lens would explain {self.lens_mm:.2g} mm" if self.lens_fitted else \
            "too few markers to fit a lens"
        smooth = (f"a smooth print or paper field {self.smooth_mm:.2g} mm"
                  if self.smooth_fitted else "too few markers to fit a print or paper field")
        return f"{lens}, {smooth}, {self.left_mm:.2g} mm left"


def _lens_model(theta, q):
    """Corners ``q`` (normalised px) through lens terms ``theta[8:12]`` (k1 k2 p1 p2), then
    the homography ``theta[:8]`` (h33 = 1): the sheet points (u, v) and the parts their
    derivatives need."""
    k1, k2, p1, p2 = theta[8:12]
    x, y = q[:, 0], q[:, 1]
    r2 = x * x + y * y
    radial = 1.0 + k1 * r2 + k2 * r2 * r2
    xu = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yu = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    H = np.append(theta[:8], 1.0).reshape(3, 3)
    w = H[2, 0] * xu + H[2, 1] * yu + H[2, 2]
    u = (H[0, 0] * xu + H[0, 1] * yu + H[0, 2]) / w
    v = (H[1, 0] * xu + H[1, 1] * yu + H[1, 2]) / w
    return u, v, xu, yu, w, H, (x, y, r2)


def _lens_residual(theta, q, mm):
    """Sheet residual (flattened: all u, then all v) of corners ``q`` (normalised px)
    through :func:`_lens_model`."""
    u, v = _lens_model(theta, q)[:2]
    return np.concatenate([u - mm[:, 0], v - mm[:, 1]])


def _lens_jacobian(theta, q, mm):
    """(2N, 12) the derivatives of :func:`_lens_residual` by ``theta``."""
    u, v, xu, yu, w, H, (x, y, r2) = _lens_model(theta, q)
    n = len(u)
    J = np.zeros((2 * n, 12))
    one = np.ones(n)
    J[:n, 0:3] = np.column_stack([xu, yu, one]) / w[:, None]
    J[n:, 3:6] = J[:n, 0:3]
    J[:n, 6:8] = -np.column_stack([u * xu, u * yu]) / w[:, None]
    J[n:, 6:8] = -np.column_stack([v * xu, v * yu]) / w[:, None]
    # through the undistorted point: d(xu, yu) / d(k1, k2, p1, p2)
    dxu = np.column_stack([x * r2, x * r2 * r2, 2 * x * y, r2 + 2 * x * x])
    dyu = np.column_stack([y * r2, y * r2 * r2, r2 + 2 * y * y, 2 * x * y])
    J[:n, 8:] = (((H[0, 0] - u * H[2, 0]) / w)[:, None] * dxu
                 + ((H[0, 1] - u * H[2, 1]) / w)[:, None] * dyu)
    J[n:, 8:] = (((H[1, 0] - v * H[2, 0]) / w)[:, None] * dxu
                 + ((H[1, 1] - v * H[2, 1]) / w)[:, None] * dyu)
    return J


def _lens_fit_residual(x0, q, mm, iterations: int = 20) -> np.ndarray:
    """The residual of :func:`_lens_residual` after the lens terms and the homography are
    fitted from ``x0`` (the one solver, :func:`vision_cal.model.solve.solve`, with the
    analytic Jacobian, at most ``iterations`` times the evaluations a step takes): a sheet
    described right converges in about five; a wrong one need not converge to be told apart
    (it leaves about the marker side), so a solve stopped on its limit is read where it
    stopped, on purpose: what a lens leaves is at most that."""
    sol = solve(lambda x: _lens_residual(x, q, mm), x0, jac=lambda x: _lens_jacobian(x, q, mm),
                xtol=1e-10, ftol=1e-10, max_nfev=5 * iterations)
    return sol.residuals if sol else sol.last.residuals


def _field_basis(xy: np.ndarray, n_corners: int) -> np.ndarray:
    """Legendre products P_i(x) P_j(y), i + j <= d, of ``xy`` in [-1, 1]: the smooth field
    over the sheet, its degree d the largest with no more terms than a sixth of the
    corners (3 with 17 markers, 7 with 60: a feed wave of a few centimetres' period)."""
    d = 3
    while (d + 2) * (d + 3) // 2 <= n_corners / 6 and d < 9:
        d += 1
    V = np.polynomial.legendre.legvander2d(xy[:, 0], xy[:, 1], [d, d])
    keep = [i * (d + 1) + j for i in range(d + 1) for j in range(d + 1) if i + j <= d]
    return V[:, keep]


def misfit_parts(corners_mm, corners_px, *, size_px=None,
                 config: SheetFitConfig | None = None) -> MisfitParts:
    """Split the marker corners' misfit to the declared sheet (:class:`MisfitParts`).
    ``size_px``: the photo's (w, h), whose centre the lens terms turn about (default: the
    corners' centre). The lens terms are fitted from ``config.lens_min_markers`` markers,
    the smooth field from ``config.smooth_min_markers`` (``vision_cal.config.SheetFitConfig``)."""
    cfg = config or DEFAULT.sheet_fit
    mm = np.asarray(corners_mm, float).reshape(-1, 2)
    px = np.asarray(corners_px, float).reshape(-1, 2)
    n_markers = len(mm) // 4
    total = _rms_mm(mm, px)
    if not np.isfinite(total):
        return MisfitParts(total, 0.0, 0.0, total, False, False)
    if size_px is not None:
        c = np.asarray(size_px, float) / 2.0
        s = float(np.hypot(*size_px)) / 2.0
    else:
        c = px.mean(axis=0)
        s = max(float(np.max(np.linalg.norm(px - c, axis=1))), 1.0)
    q = (px - c) / s
    after_lens, lens_fitted = total, False
    res = None
    if n_markers >= cfg.lens_min_markers:
        H0, _ = cv2.findHomography(q, mm, 0)
        if H0 is not None and np.all(np.isfinite(H0)) and abs(H0[2, 2]) > 1e-12:
            x0 = np.append((H0 / H0[2, 2]).ravel()[:8], np.zeros(4))
            r = _lens_fit_residual(x0, q, mm).reshape(2, -1).T
            rms = float(np.sqrt(np.mean(np.sum(r * r, axis=1))))
            if np.isfinite(rms) and rms <= total:
                after_lens, lens_fitted, res = rms, True, r
    if res is None:
        p = cv2.perspectiveTransform(px[None], cv2.findHomography(px, mm, 0)[0])[0]
        res = p - mm
    left, smooth_fitted = after_lens, False
    if n_markers >= cfg.smooth_min_markers:
        lo, hi = mm.min(axis=0), mm.max(axis=0)
        B = _field_basis((mm - (lo + hi) / 2) / np.maximum((hi - lo) / 2, 1e-9), len(mm))
        coef, *_ = np.linalg.lstsq(B, res, rcond=None)
        r = res - B @ coef
        left = float(np.sqrt(np.mean(np.sum(r * r, axis=1))))
        smooth_fitted = True
    lens_mm = float(np.sqrt(max(total ** 2 - after_lens ** 2, 0.0)))
    smooth_mm = float(np.sqrt(max(after_lens ** 2 - left ** 2, 0.0)))
    return MisfitParts(total, lens_mm, smooth_mm, left, lens_fitted, smooth_fitted)


def sheet_misfit(corners_mm, corners_px, rms_mm: float, mm_per_px: float, *, size_px=None,
                 raw_px=None, config: SheetFitConfig | None = None) -> str | None:
    """The sheet-fit gate of one photo: None when it is measured, else the one-line reason
    (:func:`misfit_reason`). Measured when the homography leaves no more than
    :func:`corner_tolerance_mm`, or when what a lens and a smooth print or paper field
    (at most ``config.smooth_max_mm``) leave is within it. With a lens applied
    (``raw_px`` given: the corners before it), that lens is a claim: the lens terms may
    then take no more than the tolerance (a declared k1 of 0.5 for none is refused and
    blamed on ``camera.dist``, not absorbed)."""
    cfg = config or DEFAULT.sheet_fit
    tol = corner_tolerance_mm(corners_mm, mm_per_px, cfg)
    if rms_mm <= tol:
        return None
    parts = misfit_parts(corners_mm, corners_px, size_px=size_px, config=cfg)
    if (parts.left_mm <= tol and parts.smooth_mm <= cfg.smooth_max_mm
            and (raw_px is None or parts.lens_mm <= tol)):
        return None
    return misfit_reason(corners_mm, corners_px, rms_mm, tol, raw_px=raw_px, config=cfg,
                         size_px=size_px, parts=parts)
