"""The sheet's height from parallax: each mark's height, and a smooth height map between.

A point of the paper raised by z above the plane of the markers is seen where its ray
meets that plane (the marker mapping's plane): moved by ``z v`` with
``v = (p - C_xy) / (C_z - z)``, C the camera centre in the sheet frame (from the marker
mapping and K). Two ways to see it:

- **against the printed grid** (one photo is enough): the grid around the dot is raised
  with it, so the marker-mapped position minus the paper position (the grid offset ``d``)
  is ``z v``: ``z = v.d / v.v``.
- **between camera places** (no grid): the marker-mapped positions ``a_k`` of the same
  mark from photos at different C_k obey ``a_k = p + z v_k``: paper position p and height
  z together, by weighted least squares, once the C_k differ enough.

Per photo the camera pose comes from the marker mapping (``H = K [r1 r2 t]``), the lens
from the session or the lens estimate; the heights are relative to the plane the marker
mapping fits, which is what ``sheet_height`` means ("above the plane of the markers").

:class:`HeightMap` is a Gaussian-process fit of the marks' heights (squared-exponential
kernel, length and amplitude by maximum marginal likelihood over a small grid, each mark's
own std as noise): a grid of heights and their std over the paper. It is claimed as the
effect ``sheet_height`` only when the marks' heights are significantly not zero
(chi-square against their std, ``alpha``), larger than ``min_claim_mm``, and *seen*
(:func:`offset_evidence`, issue 17): a smooth difference between the printed grid and the
marker mapping is also what a lens the measurement got slightly wrong makes (undeclared
and estimated, or declared wrong), seen through a tilted camera. A height moves a point
only along its parallax direction ``v``; so the grid offsets must (1) not be explained by
the field a lens error leaves on a flat sheet (radial ``r^2``, ``r^4`` about the principal
point, mapped to the sheet, plus the homography change the marker mapping absorbed;
rejected at ``alpha``), (2) be explained once a height per mark along ``v`` is added
to that field (its chi-square not significant at ``alpha``), and (3) be explained by the
heights better than by a larger noise: a height per mark takes the part of each offset
along ``v`` whatever it is, so offsets merely noisier than their stated std (a flat sheet,
the lens and mapping right) pass (1) and (2); the F ratio of the chi-square the heights
remove per parameter to what is left per dof (free of the noise's scale) must be
significant at ``alpha``. Otherwise ``not_claimed`` says why and the heights stay
reported, unclaimed.

The thresholds are config ``sheet_height`` (:class:`vision_cal.config.SheetHeightConfig`),
read from the config each function is given (default ``vision_cal.config.DEFAULT``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy import stats
from scipy.interpolate import RegularGridInterpolator

from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.errors import VisionCalError


def camera_centre_mm(H_img_sheet, K) -> np.ndarray:
    """Camera centre (3,) in the sheet frame from the plane homography (sheet mm -> ideal
    px) and K: ``K^-1 H = s [r1 r2 t]``, R made orthonormal, C = -R^T t (z > 0)."""
    M = np.linalg.solve(np.asarray(K, float), np.asarray(H_img_sheet, float))
    s = 2.0 / (np.linalg.norm(M[:, 0]) + np.linalg.norm(M[:, 1]))
    M = M * s
    if M[2, 2] < 0:  # the sheet must be in front of the camera
        M = -M
    r1, r2, t = M[:, 0], M[:, 1], M[:, 2]
    R = np.column_stack([r1, r2, np.cross(r1, r2)])
    U, _, Vt = np.linalg.svd(R)
    R = U @ Vt
    C = -R.T @ t
    if C[2] < 0:
        raise VisionCalError("the camera comes out below the sheet: bad mapping or K")
    return C


def place_of(places: list, C, fraction: float) -> int:
    """The index in ``places`` (camera centres (3,) mm, in the sheet frame) of the camera
    place of a photo taken from ``C`` (3,): the first centre closer than ``fraction`` of
    the camera's height (config ``sheet_height.same_place_fraction``), else ``C`` appended
    as a new place. Photos of one place share their pixel phase and their parallax."""
    C = np.asarray(C, float)
    k = next((i for i, c in enumerate(places) if np.linalg.norm(C - c) < fraction * C[2]),
             None)
    if k is None:
        places.append(C)
        k = len(places) - 1
    return k


@dataclass(frozen=True)
class MarkHeight:
    """A mark's height ``z_mm`` above the markers' plane, its ``std_mm``, from ``n`` photos;
    ``how``: grid | parallax; ``xy_mm`` the paper position parallax found (None: grid)."""

    z_mm: float
    std_mm: float
    n: int
    how: str
    xy_mm: np.ndarray | None = None
    cov_xy_mm2: np.ndarray | None = None

    def to_json(self) -> dict:
        """The mark's height fields of calibration.json ``marks``."""
        return {"height_mm": self.z_mm, "height_std_mm": self.std_mm, "height_from": self.how}

    def to_full_json(self) -> dict:
        """Every field (measurement.json ``heights``); :meth:`from_json` reads it back."""
        return {**self.to_json(), "n": self.n,
                "xy_mm": None if self.xy_mm is None else np.asarray(self.xy_mm).tolist(),
                "cov_xy_mm2": (None if self.cov_xy_mm2 is None
                               else np.asarray(self.cov_xy_mm2).tolist())}

    @classmethod
    def from_json(cls, d: dict) -> "MarkHeight":
        def a(k):
            return None if d.get(k) is None else np.asarray(d[k], float)

        nan = float("nan")
        return cls(nan if d.get("height_mm") is None else float(d["height_mm"]),
                   nan if d.get("height_std_mm") is None else float(d["height_std_mm"]),
                   int(d.get("n", 0)), d.get("height_from", ""), a("xy_mm"), a("cov_xy_mm2"))


def _v(p, C):
    return (np.asarray(p, float) - C[:2]) / C[2]


def height_from_grid(obs, config: EstimatorConfig | None = None) -> MarkHeight | None:
    """``obs``: list of (C (3,), p_mm (2,), d_mm (2,), cov_d (2, 2)) of one mark."""
    config = config or DEFAULT
    floor, rho = config.sheet_height.offset_floor_mm, config.association.common_fraction
    zs, ws = [], []
    for C, p, d, cov in obs:
        v = _v(p, C)
        vv = float(v @ v)
        if vv < 1e-6:
            continue  # straight below the camera: no parallax
        var_d = float(v @ cov @ v) / vv + floor**2
        zs.append(float(v @ d) / vv)
        ws.append(vv / var_d)
    if not zs:
        return None
    zs, ws = np.array(zs), np.array(ws)
    z = float(np.sum(ws * zs) / ws.sum())
    n = len(zs)
    var = (1.0 + rho * (n - 1)) / ws.sum()
    if n > 1:
        chi2 = float(np.sum(ws * (zs - z) ** 2))
        var *= max(chi2 / (n - 1), 1.0)
    return MarkHeight(z, float(np.sqrt(var)), n, "grid")


def height_from_parallax(obs, config: EstimatorConfig | None = None) -> MarkHeight | None:
    """``obs``: list of (C (3,), a_mm (2,), cov_a (2, 2)) of one mark seen through the marker
    mapping from different places: p and z by weighted least squares (a_k = p + z v_k)."""
    config = config or DEFAULT
    min_baseline, rho = (config.sheet_height.min_parallax_baseline,
                         config.association.common_fraction)
    if len(obs) < 2:
        return None
    p = np.mean([a for _, a, _ in obs], axis=0)
    for _ in range(3):
        A, b, W = [], [], []
        for C, a, cov in obs:
            v = _v(p, C)
            A.append(np.column_stack([np.eye(2), v]))
            b.append(a)
            W.append(np.linalg.inv(cov + np.eye(2) * 1e-10))
        vs = np.array([row[:, 2] for row in A])
        if np.ptp(vs, axis=0).max() < min_baseline:
            return None  # the same view every time: height and position not separable
        N = sum(Ai.T @ Wi @ Ai for Ai, Wi in zip(A, W))
        r = sum(Ai.T @ Wi @ bi for Ai, Wi, bi in zip(A, W, b))
        try:
            Ninv = np.linalg.inv(N)
        except np.linalg.LinAlgError:
            return None
        sol = Ninv @ r
        p = sol[:2]
    n = len(obs)
    res = [bi - Ai @ sol for Ai, bi in zip(A, b)]
    chi2 = float(sum(ri @ Wi @ ri for ri, Wi in zip(res, W)))
    f = max(chi2 / max(2 * n - 3, 1), 1.0)
    var = Ninv[2, 2] * f * (1.0 + rho * (n - 1))
    infl = f * (1.0 + rho * (n - 1))
    return MarkHeight(float(sol[2]), float(np.sqrt(var)), n, "parallax", sol[:2].copy(),
                      Ninv[:2, :2] * infl)


@dataclass(frozen=True)
class OffsetEvidence:
    """Whether the grid offsets are what heights make (module docstring).

    ``lens_chi2`` / ``lens_dof`` / ``p_lens``: the offsets left by a lens field and the
    mapping's homography change alone (a flat sheet); ``heights_chi2`` / ``heights_dof`` /
    ``p_heights``: those left once a height per mark along its parallax direction is
    added; ``places``: how many camera places the photos were taken from; ``gain_f`` /
    ``p_gain``: the F ratio of the chi-square the heights remove per parameter over what
    they leave per dof, and its p-value (module docstring, (3))."""

    heights_chi2: float
    heights_dof: int
    p_heights: float
    lens_chi2: float
    lens_dof: int
    p_lens: float
    places: int

    @property
    def gain_f(self) -> float:
        k = self.lens_dof - self.heights_dof
        if k <= 0 or self.heights_dof <= 0:
            return float("nan")
        return ((self.lens_chi2 - self.heights_chi2) / k) / max(
            self.heights_chi2 / self.heights_dof, 1e-300)

    @property
    def p_gain(self) -> float:
        f = self.gain_f
        return (float(stats.f.sf(f, self.lens_dof - self.heights_dof, self.heights_dof))
                if np.isfinite(f) else float("nan"))

    def not_claimed(self, alpha: float) -> tuple[str, str] | None:
        """Why heights that are significant are still not claimed: (``lens`` | ``mapping``
        | ``noise``, a sentence); None: they are seen."""
        if self.p_lens >= alpha:
            return "lens", ("the grid's offsets from the marker mapping are what a slightly wrong "
                    f"lens leaves (lens field chi2 {self.lens_chi2:.1f} on {self.lens_dof}, "
                    f"p = {self.p_lens:.2g}): a height cannot be told from the lens"
                    + ("; photograph from two or more places to see it" if self.places == 1
                       else ""))
        if self.p_heights < alpha:
            return "mapping", ("the printed grid's offsets from the marker mapping are neither a lens "
                    "error nor heights along the parallax direction (chi2 "
                    f"{self.heights_chi2:.1f} on {self.heights_dof}, p = "
                    f"{self.p_heights:.2g}): a mapping error, not the paper's height")
        if not self.p_gain < alpha:
            return "noise", ("the printed grid's offsets from the marker mapping are beyond "
                    "their stated noise, but heights along the parallax direction explain "
                    f"no more of them than a larger noise does (F = {self.gain_f:.2f} on "
                    f"{self.lens_dof - self.heights_dof} and {self.heights_dof} dof, p = "
                    f"{self.p_gain:.2g}): the offsets' noise, not the paper's height")
        return None

    def to_json(self) -> dict:
        return {"lens_field_fit": {"chi2": self.lens_chi2, "dof": self.lens_dof,
                                   "p_value": self.p_lens},
                "heights_fit": {"chi2": self.heights_chi2, "dof": self.heights_dof,
                                "p_value": self.p_heights},
                "heights_gain": {"F": self.gain_f, "p_value": self.p_gain},
                "camera_places": self.places}


def _lens_fields(p, H, K) -> np.ndarray:
    """(2, 10) sheet-mm displacement fields at sheet point ``p`` of a photo (H: sheet mm ->
    ideal px, K): radial r^2, r^4 about the principal point, then a homography change."""
    H = np.asarray(H, float)
    K = np.asarray(K, float)
    x, y = (float(c) for c in p)
    w = H @ [x, y, 1.0]
    u = w[:2] / w[2]
    J = (H[:2, :2] - np.outer(u, H[2, :2])) / w[2]      # d(ideal px) / d(sheet mm)
    f = np.array([K[0, 0], K[1, 1]])
    n = (u - K[:2, 2]) / f
    r2 = float(n @ n)
    Jinv = np.linalg.inv(J)
    lens = [Jinv @ (f * n * r2), Jinv @ (f * n * r2**2)]
    a, b = x / 100.0, y / 100.0        # 100 mm units: columns of similar size
    hom = [[1, 0], [0, 1], [a, 0], [b, 0], [0, a], [0, b], [a * a, a * b], [a * b, b * b]]
    return np.column_stack([*lens, *np.asarray(hom, float)])


def _fit_chi2(A, b) -> tuple[float, int, float]:
    """Weighted (already whitened) least squares: chi-square, its dof and p-value."""
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    chi2 = float(np.sum((b - A @ sol) ** 2))
    dof = int(len(b) - np.linalg.matrix_rank(A))
    return chi2, dof, float(stats.chi2.sf(chi2, dof)) if dof > 0 else float("nan")


def offset_evidence(obs_by_mark: dict,
                    config: EstimatorConfig | None = None) -> OffsetEvidence | None:
    """The two fits of the module docstring on the grid observations: one row pair per mark
    and camera place (its photos' weighted mean, whose variance keeps the common part of
    photos from one place, config ``association.common_fraction``), whitened by its
    covariance (each photo's plus ``sheet_height.offset_floor_mm``); each camera place has
    its own homography change (the marker mapping absorbs part of any error, and of the
    markers' own heights).

    - lens (the sheet flat): the two radial lens fields shared by all photos, plus the
      homography fields;
    - heights: a height per mark along its parallax direction, plus the lens and the
      homography fields (a lens estimated from bumped paper is a little off too).

    ``obs_by_mark``: mark id -> list of (C (3,), p_mm (2,), d_mm (2,), cov_d (2, 2),
    H_img_sheet (3, 3), K (3, 3)). None when fewer marks than the heights fit can test."""
    config = config or DEFAULT
    hc, rho = config.sheet_height, config.association.common_fraction
    obs_by_mark = {k: v for k, v in obs_by_mark.items() if v}
    places: list[np.ndarray] = []
    groups: dict = {}     # (mark, place) -> [(W, d, v, F)]: one row pair per mark and place
    for m, obs in enumerate(obs_by_mark.values()):
        for C, p, d, cov, H, K in obs:
            k = place_of(places, C, hc.same_place_fraction)
            W = np.linalg.inv(np.asarray(cov, float) + np.eye(2) * hc.offset_floor_mm**2)
            groups.setdefault((m, k), []).append((W, np.asarray(d, float), _v(p, C),
                                                  _lens_fields(p, H, K)))
    rows = []
    for (m, k), g in groups.items():   # photos of one place share their pixel phase
        Ws = sum(W for W, *_ in g)
        Wi = np.linalg.inv(Ws)
        d = Wi @ sum(W @ dd for W, dd, _, _ in g)
        F = Wi @ sum(W @ FF for W, _, _, FF in g)
        v = np.mean([vv for _, _, vv, _ in g], axis=0)
        Wm = Ws / (1.0 + rho * (len(g) - 1))
        rows.append((m, k, np.linalg.cholesky(Wm).T, v, F, d))
    n_marks, n_places = len(obs_by_mark), len(places)
    Z = np.zeros((2 * len(rows), n_marks))
    Hm = np.zeros((2 * len(rows), 8 * n_places))
    Ln = np.zeros((2 * len(rows), 2))
    y = np.zeros(2 * len(rows))
    for r, (m, k, L, v, F, d) in enumerate(rows):
        sl = slice(2 * r, 2 * r + 2)
        Z[sl, m] = L @ v
        Hm[sl, 8 * k:8 * k + 8] = L @ F[:, 2:]
        Ln[sl] = L @ F[:, :2]
        y[sl] = L @ d
    h_chi2, h_dof, p_h = _fit_chi2(np.hstack([Z, Ln, Hm]), y)
    if h_dof < 3:
        return None
    l_chi2, l_dof, p_l = _fit_chi2(np.hstack([Ln, Hm]), y)
    return OffsetEvidence(h_chi2, h_dof, p_h, l_chi2, l_dof, p_l, n_places)


@dataclass(frozen=True)
class HeightMap:
    """Heights over the paper: ``z_mm`` / ``std_mm`` (ny, nx) at ``x_mm`` (nx,), ``y_mm``
    (ny,); the marks it was fitted to; the chi-square test that the sheet is flat."""

    x_mm: np.ndarray
    y_mm: np.ndarray
    z_mm: np.ndarray
    std_mm: np.ndarray
    length_mm: float
    amplitude_mm: float
    chi2: float
    dof: int
    p_flat: float
    max_abs_mark_mm: float
    claimed: bool
    marks: dict = field(default_factory=dict)
    evidence: OffsetEvidence | None = None
    not_claimed: str | None = None       # why significant heights are not claimed
    not_claimed_as: str | None = None    # what the offsets are instead: lens | mapping | noise

    @classmethod
    def from_estimate(cls, xy_mm, z_mm, std_mm, extent_mm, *, ids=(),
                      evidence: OffsetEvidence | None = None,
                      config: EstimatorConfig | None = None) -> "HeightMap":
        """``evidence``: :func:`offset_evidence` of the grid offsets the heights came from
        (None: heights from parallax between places, their own evidence); ``config``: its
        ``sheet_height`` level, claim size and grid step (default ``DEFAULT``)."""
        hc = (config or DEFAULT).sheet_height
        alpha, step_mm = hc.alpha, hc.map_step_mm
        xy = np.asarray(xy_mm, float).reshape(-1, 2)
        z = np.asarray(z_mm, float).ravel()
        sd = np.asarray(std_mm, float).ravel()
        if len(z) < 3:
            raise VisionCalError(f"{len(z)} mark heights cannot make a height map")
        D2 = np.sum((xy[:, None] - xy[None]) ** 2, axis=2)
        best = None
        for ell in (30.0, 50.0, 80.0, 130.0, 200.0, 320.0):
            for amp in (0.02, 0.05, 0.1, 0.2, 0.4, 0.8, 1.6):
                Kx = amp**2 * np.exp(-D2 / (2 * ell**2)) + np.diag(sd**2)
                try:
                    L = np.linalg.cholesky(Kx)
                except np.linalg.LinAlgError:
                    continue
                al = np.linalg.solve(L, z)
                ll = -0.5 * al @ al - np.sum(np.log(np.diag(L)))
                if best is None or ll > best[0]:
                    best = (ll, ell, amp)
        _, ell, amp = best
        x0, y0, x1, y1 = (float(v) for v in extent_mm)
        xs = np.arange(x0, x1 + 1e-9, step_mm)
        ys = np.arange(y0, y1 + 1e-9, step_mm)
        X, Y = np.meshgrid(xs, ys)
        P = np.column_stack([X.ravel(), Y.ravel()])
        Kx = amp**2 * np.exp(-D2 / (2 * ell**2)) + np.diag(sd**2)
        Ks = amp**2 * np.exp(-np.sum((P[:, None] - xy[None]) ** 2, axis=2) / (2 * ell**2))
        Kinv = np.linalg.inv(Kx)
        mean = Ks @ Kinv @ z
        var = np.maximum(amp**2 - np.einsum("ij,jk,ik->i", Ks, Kinv, Ks), 0.0)
        chi2 = float(np.sum((z / sd) ** 2))
        p = float(stats.chi2.sf(chi2, len(z)))
        max_abs = float(np.max(np.abs(z)))
        significant = bool(p < alpha and max_abs > hc.min_claim_mm)
        why = evidence.not_claimed(alpha) if significant and evidence is not None else None
        kind, why = why if why is not None else (None, None)
        marks = {str(i): {"xy_mm": xy[k].tolist(), "height_mm": float(z[k]),
                          "height_std_mm": float(sd[k])} for k, i in enumerate(ids)}
        return cls(xs, ys, mean.reshape(X.shape), np.sqrt(var).reshape(X.shape), ell, amp,
                   chi2, len(z), p, max_abs, significant and why is None, marks, evidence,
                   why, kind)

    def at(self, xy_mm) -> np.ndarray:
        """The map's height (N,) at sheet points (bilinear in the grid)."""
        f = RegularGridInterpolator((self.y_mm, self.x_mm), self.z_mm, bounds_error=False,
                                    fill_value=None)
        p = np.asarray(xy_mm, float).reshape(-1, 2)
        return f(p[:, ::-1])

    def to_json(self, *, decimals: int | None = 5) -> dict:
        """calibration.json ``diagnosis.sheet_height``: heights to 1e-5 mm (``decimals``;
        None: as computed, measurement.json)."""
        def r(a):
            return (a if decimals is None else np.round(a, decimals)).tolist()

        return {"claimed": self.claimed,
                "grid": {"x_mm": self.x_mm.tolist(), "y_mm": self.y_mm.tolist(),
                         "z_mm": r(self.z_mm), "std_mm": r(self.std_mm)},
                "flat_test": {"chi2": self.chi2, "dof": self.dof, "p_value": self.p_flat},
                "max_abs_mark_height_mm": self.max_abs_mark_mm,
                "smoothness": {"length_mm": self.length_mm, "amplitude_mm": self.amplitude_mm},
                "marks": self.marks,
                **({} if self.evidence is None else {"evidence": self.evidence.to_json()}),
                **({} if self.not_claimed is None else {"not_claimed": self.not_claimed,
                                                         "not_claimed_as": self.not_claimed_as})}

    @classmethod
    def from_json(cls, d: dict) -> "HeightMap":
        """Back from :meth:`to_json`."""
        g, ft, sm = d["grid"], d["flat_test"], d["smoothness"]
        return cls(np.asarray(g["x_mm"], float), np.asarray(g["y_mm"], float),
                   np.asarray(g["z_mm"], float), np.asarray(g["std_mm"], float),
                   float(sm["length_mm"]), float(sm["amplitude_mm"]), float(ft["chi2"]),
                   int(ft["dof"]), float(ft["p_value"]), float(d["max_abs_mark_height_mm"]),
                   bool(d["claimed"]), dict(d.get("marks") or {}))

    def to_effect_json(self) -> dict:
        """calibration.json's ``sheet_height`` effect: a grid of heights (mm) and its std."""
        d = self.to_json()
        return {"name": "sheet_height", "grid": d["grid"], "flat_test": d["flat_test"],
                "max_abs_mark_height_mm": self.max_abs_mark_mm,
                "smoothness": d["smoothness"],
                "reference": "the plane of the markers (z up towards the camera)"}


def sheet_heights(images, marks: dict, groups_of: dict, extent_mm, *, K_fallback=None,
                  config: EstimatorConfig | None = None):
    """Heights of the measured marks and the map between them.

    ``images``: the measured :class:`vision_cal.measure.types.ImageResult` list;
    ``marks``: id -> MarkMeasurement;
    ``groups_of``: id -> list of (image index, dot index). Returns (heights: id ->
    MarkHeight, HeightMap or None, note or None). ``config``: the thresholds (default
    ``vision_cal.config.DEFAULT``).
    """
    config = config or DEFAULT
    centres = {}
    for k, im in enumerate(images):
        if im.status != "ok" or im.mapping is None:
            continue
        K = im.K if im.K is not None else K_fallback
        if K is None:
            continue
        try:
            centres[k] = camera_centre_mm(im.mapping.H_img_sheet, K)
        except (VisionCalError, np.linalg.LinAlgError):
            continue
    if not centres:
        return {}, None, "no camera pose: the lens is unknown, heights are not observable"
    heights, evidence_obs = {}, {}
    for mid, pairs in groups_of.items():
        grid_obs, par_obs = [], []
        for k, j in pairs:
            if k not in centres:
                continue
            im = images[k]
            C = centres[k]
            par_obs.append((C, im.dots_global_xy_mm[j], im.dots_global_cov_mm2[j]))
            if im.dots_reference[j] == "grid":
                grid_obs.append((C, im.dots_xy_mm[j], im.dots_grid_offset_mm[j],
                                 im.dots_grid_offset_cov_mm2[j]))
                evidence_obs.setdefault(mid, []).append(
                    (*grid_obs[-1], im.mapping.H_img_sheet,
                     im.K if im.K is not None else K_fallback))
        h = (height_from_grid(grid_obs, config) if grid_obs
             else height_from_parallax(par_obs, config))
        if h is not None:
            heights[mid] = h
    if len(heights) < 3:
        return heights, None, (f"heights of {len(heights)} marks only: no height map "
                               "(no printed grid and a camera that did not move?)")
    ids = sorted(heights)
    xy = [heights[i].xy_mm if heights[i].xy_mm is not None else marks[i].xy_mm for i in ids]
    grid_ids = [i for i in ids if heights[i].how == "grid"]
    evidence = offset_evidence({i: evidence_obs[i] for i in grid_ids}, config)
    hm = HeightMap.from_estimate(xy, [heights[i].z_mm for i in ids],
                                 [heights[i].std_mm for i in ids], extent_mm, ids=ids,
                                 evidence=evidence, config=config)
    if hm.claimed and evidence is None and len(grid_ids) == len(ids):
        # every height from the grid, too few offsets to test them against a lens or
        # mapping field (or a print no survey measured): not seen (issue 37: one photo of
        # 9 marks on a print 0.15 mm off claimed 2.5 mm of height)
        hm = replace(hm, claimed=False, not_claimed_as="untested", not_claimed=(
            f"the grid's offsets of {len(ids)} marks cannot tell heights from a lens, mapping "
            "or print field (too few marks for the test): draw more marks or photograph "
            "from two or more places to see it"))
    return heights, hm, None
