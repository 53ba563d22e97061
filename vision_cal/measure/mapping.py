"""Image -> sheet mapping: lens (optional) then a plane homography.

Conventions
-----------
- Image pixels follow OpenCV: (u, v) = (column, row), integer at pixel centres.
- *Raw* pixels are where things appear in the photograph; *ideal* pixels are where a
  pinhole camera with the same ``K`` would see them (``cv2.undistortPoints(..., P=K)``).
  Without a lens model ideal == raw.
- ``SheetMapping.H_img_sheet`` (3, 3) maps sheet mm (x right, y up) to ideal pixels;
  ``G_sheet_img`` is its inverse.
- :class:`LensEstimate` is the lens found in the photos when ``session.camera`` is absent:
  OpenCV ``K`` and ``dist`` (k1 k2 p1 p2 k3); the principal point starts at the image
  centre and is free in the ``k1k2_pp`` model (phones: often tens of pixels off).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from vision_cal.errors import VisionCalError
from vision_cal.model.rms import rms_2d
from vision_cal.model.solve import covariance

_UNDIST_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 60, 1e-12)


# --------------------------------------------------------------------------- lens helpers

def undistort_px(uv_px, K, dist) -> np.ndarray:
    """Raw pixels (N, 2) -> ideal pixels (N, 2) (identity when ``K`` is None)."""
    uv = np.asarray(uv_px, dtype=np.float64).reshape(-1, 2)
    if K is None or len(uv) == 0:
        return uv.copy()
    out = cv2.undistortPoints(uv.reshape(-1, 1, 2), np.asarray(K, float),
                              np.asarray(dist, float), P=np.asarray(K, float),
                              criteria=_UNDIST_CRITERIA)
    return np.asarray(out, dtype=np.float64).reshape(-1, 2)


def distort_px(uv_ideal, K, dist) -> np.ndarray:
    """Ideal pixels (N, 2) -> raw pixels (N, 2) (identity when ``K`` is None)."""
    uv = np.asarray(uv_ideal, dtype=np.float64).reshape(-1, 2)
    if K is None or len(uv) == 0:
        return uv.copy()
    K = np.asarray(K, float)
    xn = (uv[:, 0] - K[0, 2]) / K[0, 0]
    yn = (uv[:, 1] - K[1, 2]) / K[1, 1]
    if not np.any(dist):   # no lens distortion: what cv2.projectPoints computes, in numpy
        return np.column_stack([xn * K[0, 0] + K[0, 2], yn * K[1, 1] + K[1, 2]])
    pts = np.column_stack([xn, yn, np.ones_like(xn)])
    out, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K,
                               np.asarray(dist, float))
    return np.asarray(out, dtype=np.float64).reshape(-1, 2)


def apply_h(H, xy) -> np.ndarray:
    """Apply a 3x3 homography to points (N, 2)."""
    p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    q = p @ H[:, :2].T + H[:, 2]
    return q[:, :2] / q[:, 2:3]


def _normaliser(p: np.ndarray) -> np.ndarray:
    c = p.mean(axis=0)
    s = np.sqrt(2.0) / max(np.sqrt(((p - c) ** 2).sum(axis=1)).mean(), 1e-12)
    return np.array([[s, 0, -s * c[0]], [0, s, -s * c[1]], [0, 0, 1.0]])


def _h_jacobian(Gn: np.ndarray, src_n: np.ndarray) -> np.ndarray:
    """d dst_n / d g (N, 2, 8) for the homography Gn (g33 = 1) at normalised src points."""
    x, y = src_n[:, 0], src_n[:, 1]
    q = np.column_stack([x, y, np.ones_like(x)]) @ Gn.T
    u, v, c = q[:, 0] / q[:, 2], q[:, 1] / q[:, 2], q[:, 2]
    J = np.zeros((len(x), 2, 8))
    J[:, 0, 0], J[:, 0, 1], J[:, 0, 2] = x / c, y / c, 1 / c
    J[:, 1, 3], J[:, 1, 4], J[:, 1, 5] = x / c, y / c, 1 / c
    J[:, 0, 6], J[:, 0, 7] = -u * x / c, -u * y / c
    J[:, 1, 6], J[:, 1, 7] = -v * x / c, -v * y / c
    return J


@dataclass(frozen=True)
class SheetMapping:
    """Raw image pixels <-> sheet mm for one photograph.

    ``H_img_sheet`` (3, 3): sheet mm -> ideal px. ``K`` (3, 3) / ``dist`` (n,) the lens
    (None: raw == ideal). ``corner_rms_px`` / ``corner_rms_mm``: RMS of the marker-corner
    residuals (raw px, and the detected corners mapped to the sheet, in mm). ``cov_g``
    (8, 8) covariance of the normalised inverse homography; ``T_src`` / ``T_dst`` its
    normalisers (ideal px, sheet mm).
    """

    H_img_sheet: np.ndarray
    K: np.ndarray | None = None
    dist: np.ndarray | None = None
    corner_rms_px: float = float("nan")
    corner_rms_mm: float = float("nan")
    n_corners: int = 0
    cov_g: np.ndarray | None = field(default=None, repr=False)
    T_src: np.ndarray | None = field(default=None, repr=False)
    T_dst: np.ndarray | None = field(default=None, repr=False)

    def to_json(self) -> dict:
        """Every field, as lists (measurement.json); :meth:`from_json` reads it back."""
        def a(v):
            return None if v is None else np.asarray(v, float).tolist()

        return {"H_img_sheet": a(self.H_img_sheet), "K": a(self.K), "dist": a(self.dist),
                "corner_rms_px": float(self.corner_rms_px),
                "corner_rms_mm": float(self.corner_rms_mm), "n_corners": int(self.n_corners),
                "cov_g": a(self.cov_g), "T_src": a(self.T_src), "T_dst": a(self.T_dst)}

    @classmethod
    def from_json(cls, d: dict) -> "SheetMapping":
        def a(k):
            return None if d.get(k) is None else np.asarray(d[k], float)

        def f(k):
            return float("nan") if d.get(k) is None else float(d[k])

        return cls(a("H_img_sheet"), a("K"), a("dist"), f("corner_rms_px"), f("corner_rms_mm"),
                   int(d.get("n_corners", 0)), a("cov_g"), a("T_src"), a("T_dst"))

    @property
    def G_sheet_img(self) -> np.ndarray:
        return np.linalg.inv(self.H_img_sheet)

    def image_to_sheet(self, uv_px) -> np.ndarray:
        """Raw pixels (N, 2) -> sheet mm (N, 2)."""
        return apply_h(self.G_sheet_img, undistort_px(uv_px, self.K, self.dist))

    def sheet_to_image(self, xy_mm) -> np.ndarray:
        """Sheet mm (N, 2) -> raw pixels (N, 2)."""
        return distort_px(apply_h(self.H_img_sheet, xy_mm), self.K, self.dist)

    def mm_per_px(self, xy_mm) -> np.ndarray:
        """Local linear size of one raw pixel on the sheet (N,) mm, sqrt(|det J|)."""
        xy = np.asarray(xy_mm, float).reshape(-1, 2)
        e = 0.5
        # every point and its two neighbours through the mapping at once
        q = self.sheet_to_image(np.stack([xy, xy + [e, 0], xy + [0, e]], axis=1)
                                ).reshape(-1, 3, 2)
        a = q[:, 1] - q[:, 0]
        b = q[:, 2] - q[:, 0]
        det = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) / (e * e)  # px^2 per mm^2
        return 1.0 / np.sqrt(np.maximum(det, 1e-12))

    def point_cov_mm2(self, xy_mm) -> np.ndarray:
        """Covariance (N, 2, 2) mm^2 of mapped sheet points due to the homography fit."""
        xy = np.asarray(xy_mm, float).reshape(-1, 2)
        if self.cov_g is None:
            return np.zeros((len(xy), 2, 2))
        uv = apply_h(self.H_img_sheet, xy)
        src_n = apply_h(self.T_src, uv)
        Gn = self.T_dst @ self.G_sheet_img @ np.linalg.inv(self.T_src)
        Gn = Gn / Gn[2, 2]
        J = _h_jacobian(Gn, src_n)
        s = self.T_dst[0, 0]
        return np.einsum("nik,kl,njl->nij", J, self.cov_g, J) / s**2


def fit_mapping(sheet_mm, raw_px, *, K=None, dist=None) -> SheetMapping:
    """Fit the homography of one photo from matched points (N, 2) sheet mm / raw px.

    Least squares on the ideal-pixel reprojection error (``cv2.findHomography``, method 0,
    which ends with Levenberg-Marquardt), plus the covariance of the inverse map from the
    residual scatter.
    """
    obj = np.asarray(sheet_mm, float).reshape(-1, 2)
    raw = np.asarray(raw_px, float).reshape(-1, 2)
    if len(obj) < 8:
        raise VisionCalError(f"{len(obj)} corners cannot fix a homography with its uncertainty")
    uv = undistort_px(raw, K, dist)
    H, _ = cv2.findHomography(obj, uv, 0)
    if H is None or not np.all(np.isfinite(H)):
        raise VisionCalError("degenerate marker corners: no homography")
    pred = distort_px(apply_h(H, obj), K, dist)
    res_px = raw - pred
    rms_px = rms_2d(res_px)
    G = np.linalg.inv(H)
    back = apply_h(G, uv)
    res_mm = back - obj
    rms_mm = rms_2d(res_mm)
    # covariance of the inverse homography (ideal px -> sheet mm), normalised coordinates
    Ts, Td = _normaliser(uv), _normaliser(obj)
    Gn = Td @ G @ np.linalg.inv(Ts)
    Gn = Gn / Gn[2, 2]
    J = _h_jacobian(Gn, apply_h(Ts, uv)).reshape(-1, 8)
    if len(obj) % 4 == 0 and len(obj) >= 24:
        # corners come 4 per marker: their biases (a marker looking a little larger or
        # smaller) cancel in the fit, so the noise that matters is that of marker centres
        rc = res_mm.reshape(-1, 4, 2).mean(axis=1)
        s2 = 4.0 * float(np.sum(rc**2)) / max(2 * len(rc) - 8, 1)
    else:
        s2 = float(np.sum(res_mm**2)) / max(2 * len(obj) - 8, 1)
    s2 *= Td[0, 0] ** 2
    c = covariance(J, s2=s2)      # the one policy; corners that do not fix it: no covariance
    cov = None if c.not_fixed else c.matrix
    return SheetMapping(H, None if K is None else np.asarray(K, float),
                        None if dist is None else np.asarray(dist, float),
                        rms_px, rms_mm, len(obj), cov, Ts, Td)


# --------------------------------------------------------------------------- lens estimate

#: candidate lens models, simplest first: (name, calibrateCamera flags for free terms)
_BASE_FLAGS = (cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_PRINCIPAL_POINT
               | cv2.CALIB_FIX_ASPECT_RATIO)
#: the principal point is where the radial distortion is centred; a phone's is often
#: tens of pixels off the image centre: a model with it free competes on held-out corners
_FREE_PP_FLAGS = cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_ASPECT_RATIO
LENS_MODELS = (
    ("k1k2", _BASE_FLAGS | cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3),
    ("k1k2_pp", _FREE_PP_FLAGS | cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3),
    ("k1k2k3p1p2", _BASE_FLAGS),
)


@dataclass(frozen=True)
class LensEstimate:
    """The lens found in the photos (``session.camera`` absent).

    ``kept``: whether held-out corners say the model helps (only then is it used and reported
    as the effect ``lens_distortion``). ``model`` names the free terms; ``K`` (3, 3) and
    ``dist`` (5,) OpenCV k1 k2 p1 p2 k3. ``rms_px_before/after`` and ``rms_mm_*``: in-sample
    marker-corner residual RMS with a plain homography / with the lens; ``cv_rms_px_*``:
    the same on held-out markers.
    """

    kept: bool
    model: str
    K: np.ndarray
    dist: np.ndarray
    size_px: tuple[int, int]
    rms_px_before: float
    rms_px_after: float
    rms_mm_before: float
    rms_mm_after: float
    cv_rms_px_before: float
    cv_rms_px_after: float
    n_photos: int
    candidates: dict = field(default_factory=dict, compare=False)
    #: added: photos of the transposed size are the same camera turned this way (+1 / -1,
    #: :mod:`vision_cal.measure.rotated`); 0 when there are none
    turned: int = 0

    @property
    def coefficients(self) -> list[float]:
        return [float(v) for v in np.asarray(self.dist).ravel()]

    def to_effect_json(self) -> dict:
        return {"name": "lens_distortion", "model": f"opencv_{self.model}",
                "coefficients": self.coefficients,
                "coefficient_names": ["k1", "k2", "p1", "p2", "k3"],
                "K": np.asarray(self.K).tolist(), "size_px": list(self.size_px),
                "corner_rms_px": {"before": self.rms_px_before, "after": self.rms_px_after},
                "corner_rms_mm": {"before": self.rms_mm_before, "after": self.rms_mm_after},
                "heldout_corner_rms_px": {"before": self.cv_rms_px_before,
                                          "after": self.cv_rms_px_after},
                "n_photos": self.n_photos}

    def to_json(self) -> dict:
        """measurement.json ``lens``: the effect's fields plus ``kept``, the candidate
        models' held-out RMS and ``turned``; :meth:`from_json` reads it back."""
        return {**self.to_effect_json(), "kept": self.kept,
                "candidates_heldout_rms_px": self.candidates, "turned": self.turned}

    @classmethod
    def from_json(cls, d: dict) -> "LensEstimate":
        def f(v):
            return float("nan") if v is None else float(v)

        px, mm, cv = d["corner_rms_px"], d["corner_rms_mm"], d["heldout_corner_rms_px"]
        model = str(d["model"])
        return cls(bool(d["kept"]), model[len("opencv_"):] if model.startswith("opencv_")
                   else model, np.asarray(d["K"], float), np.asarray(d["coefficients"], float),
                   tuple(int(v) for v in d["size_px"]), f(px["before"]), f(px["after"]),
                   f(mm["before"]), f(mm["after"]), f(cv["before"]), f(cv["after"]),
                   int(d["n_photos"]), dict(d.get("candidates_heldout_rms_px") or {}),
                   int(d.get("turned", 0)))


def _calibrate(views, size_px, flags, f0):
    w, h = size_px
    K0 = np.array([[f0, 0, (w - 1) / 2.0], [0, f0, (h - 1) / 2.0], [0, 0, 1.0]])
    obj = [np.column_stack([o, np.zeros(len(o))]).astype(np.float32) for o, _ in views]
    img = [np.asarray(i, np.float32).reshape(-1, 1, 2) for _, i in views]
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-10)
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(obj, img, (w, h), K0, np.zeros(5),
                                                     flags=flags, criteria=crit)
    return np.asarray(K, float), np.asarray(dist, float).ravel()[:5], rvecs, tvecs


def _project(obj_mm, K, dist, rvec, tvec):
    pts = np.column_stack([obj_mm, np.zeros(len(obj_mm))]).astype(np.float64)
    out, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), rvec, tvec, K, dist)
    return np.asarray(out, float).reshape(-1, 2)


def estimate_lens(views, size_px, *, n_folds: int = 3, min_gain: float = 0.8,
                  min_gain_px: float = 0.02) -> LensEstimate | None:
    """Fit a lens jointly over photos of one camera, keep it only if held-out corners agree.

    ``views``: list of (marker_ids (M,), corners_mm (M, 4, 2), corners_px (M, 4, 2)).
    Shared intrinsics (unknown focal; principal point at the image centre, or free in the
    ``k1k2_pp`` model) and distortion,
    one pose per photo. Markers are split into ``n_folds`` interleaved folds; each model is
    fitted without one fold and scored on its corners. A model is kept when its held-out
    RMS is below ``min_gain`` x and ``min_gain_px`` below the plain homography's; a richer
    model must beat the simpler one by the same margins. Returns None with no usable views.
    """
    views = [(np.asarray(i), np.asarray(o, float), np.asarray(p, float)) for i, o, p in views
             if len(i) >= 4]
    if not views:
        return None
    f0 = 1.2 * max(size_px)
    all_ids = np.unique(np.concatenate([v[0] for v in views]))
    fold_of = {int(m): k % n_folds for k, m in enumerate(all_ids)}

    def flat(sel_views):
        return [(o.reshape(-1, 2), p.reshape(-1, 2)) for _, o, p in sel_views]

    # held-out scores
    res_none, res_model = [], {name: [] for name, _ in LENS_MODELS}
    for k in range(n_folds):
        train, test = [], []
        for ids, o, p in views:
            f = np.array([fold_of[int(m)] for m in ids])
            tr, te = f != k, f == k
            if tr.sum() >= 4 and te.sum() >= 1:
                train.append((ids[tr], o[tr], p[tr]))
                test.append((o[te].reshape(-1, 2), p[te].reshape(-1, 2)))
        if not train:
            continue
        for (_, o, p), (ot, pt) in zip(train, test):
            H, _ = cv2.findHomography(o.reshape(-1, 2), p.reshape(-1, 2), 0)
            res_none.append(pt - apply_h(H, ot))
        for name, flags in LENS_MODELS:
            try:
                K, dist, rv, tv = _calibrate(flat(train), size_px, flags, f0)
            except cv2.error:
                res_model[name].append(np.full((1, 2), np.inf))
                continue
            for (ot, pt), r_, t_ in zip(test, rv, tv):
                res_model[name].append(pt - _project(ot, K, dist, r_, t_))
    cv_none = rms_2d(np.concatenate(res_none)) if res_none else float("nan")
    cv = {n: (rms_2d(np.concatenate(r)) if r else float("nan")) for n, r in res_model.items()}

    chosen, cv_best = None, cv_none
    for name, _ in LENS_MODELS:
        c = cv[name]
        if np.isfinite(c) and c < min_gain * cv_best and cv_best - c > min_gain_px:
            chosen, cv_best = name, c

    # in-sample figures, before and after
    flat_all = flat(views)
    res_b, res_b_mm = [], []
    for o, p in flat_all:
        H, _ = cv2.findHomography(o, p, 0)
        res_b.append(p - apply_h(H, o))
        res_b_mm.append(apply_h(np.linalg.inv(H), p) - o)
    name = chosen or LENS_MODELS[0][0]
    flags = dict(LENS_MODELS)[name]
    try:
        K, dist, rv, tv = _calibrate(flat_all, size_px, flags, f0)
    except cv2.error:
        return None
    res_a, res_a_mm = [], []
    for o, p in flat_all:
        m = fit_mapping(o, p, K=K, dist=dist)
        res_a.append(p - m.sheet_to_image(o))
        res_a_mm.append(m.image_to_sheet(p) - o)
    return LensEstimate(
        kept=chosen is not None, model=name, K=K, dist=dist,
        size_px=(int(size_px[0]), int(size_px[1])),
        rms_px_before=rms_2d(np.concatenate(res_b)), rms_px_after=rms_2d(np.concatenate(res_a)),
        rms_mm_before=rms_2d(np.concatenate(res_b_mm)), rms_mm_after=rms_2d(np.concatenate(res_a_mm)),
        cv_rms_px_before=cv_none, cv_rms_px_after=cv.get(name, float("nan")),
        n_photos=len(views), candidates={"none": cv_none, **cv})
