"""A camera on the arm: the robot and ``T_flange_camera`` from photos of the fixed sheet.

Each photo is taken with the arm at commanded joints ``q`` (and ``j4_deg``) and sees some
of the sheet's markers. The model (``docs/format.md``, "The robot frame and cameras"):

    T_sheet_camera(q) = T_sheet_flange(q) @ T_flange_camera
    T_sheet_flange(q): origin base + L1 [cos phi1, sin phi1] + L2 [cos phi12, sin phi12]
                       in the sheet's plane (z = 0), x axis at phi12 + q4, z up

(``phi1 = q1 + z1``, ``phi12 = phi1 + q2 + z2``; joint 4's zero is part of
``T_flange_camera``). The fit is on the marker corners' reprojection error in every photo
(sub-pixel corners of the measurement stage), jointly over the six base parameters and the
six of ``T_flange_camera`` (rotation vector, translation), by Levenberg-Marquardt from the
nominal robot and the first photo's pose.

Why the height is found: SCARA motion is planar (rotations about z, translations in the
plane), so relative motions between photos, which is what classic hand-eye (AX = XB) uses,
are the same for every camera height (``tests/camera/test_arm.py``). The sheet's plane is the
flange frame's z = 0 by definition, and each photo's pose *in the sheet frame* gives the
camera's height above it directly.

What it cannot find: with ``q4`` the same in every photo (or a camera on link 2) the
camera's offset along link 2 and ``L2`` (and its sideways offset and ``z2``) move every
photo alike; the covariance then shows them unidentified (``not_identifiable``): turn
joint 4 between photos (``vision-cal design --camera-on-arm`` plans it).

An undeclared lens (issue 37): its focal length trades with the camera's height, so the
lens's covariance (:func:`estimate_lens`, clustered by photo) is carried through the fit
into the parameters' (:func:`fit_arm_camera` ``lens_cov``), and :func:`camera_for` hands
``locate`` the camera's 9x9 covariance with the lens's terms: the sheet's plane keeps its
std, a point above it carries the focal length's. Markers found pixels off their photo's
own pose fit are left out first (:func:`without_misdetected`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from vision_cal.camera.fixed import (F_REL_STD_MAX, UNDETERMINED, FixedCamera, T_sheet_robot,
                                     camera_of, fit_pose, homogeneous,
                                     pose_delta)
from vision_cal.config import DEFAULT, VerdictConfig
from vision_cal.dataset.camera_block import check_camera_entry
from vision_cal.errors import CalibrationError, VisionCalError
from vision_cal.measure.types import ImageDetections
from vision_cal.model.kinematics import ScaraParams, flange_angle_rad, forward
from vision_cal.model.rms import rms_2d
from vision_cal.model.solve import covariance, solve

LABELS = ("L1_mm", "L2_mm", "z1_deg", "z2_deg", "base_x_mm", "base_y_mm",
          "cam_rot_x_deg", "cam_rot_y_deg", "cam_rot_z_deg", "cam_x_mm", "cam_y_mm",
          "cam_z_mm")
#: fewer photos leave too few degrees of freedom to estimate the photo-level variances
MIN_POSES = 6
#: a parameter whose std is above this (its unit: mm or deg) is reported not identifiable
UNIDENTIFIED_STD = 1.0


def lens_corners(det: ImageDetections, K=None, dist=None) -> np.ndarray:
    """(4M, 2) a photo's marker corners in raw px, found in the lens ``(K, dist)``.

        corners_px = lens_corners(det, K, dist)       # det: stage 1's ImageDetections

    The markers' borders are fitted as straight lines in the lens's ideal pixels, as the
    pen's measurement finds them (:meth:`vision_cal.measure.types.ImageDetections.corners_for`);
    a lens without distortion, or none, fits them in the photo's own pixels. A marker's
    straight border is curved in a distorted photo: a line fitted to it there biases the
    corner by a few hundredths of a pixel, differently across the image (with k1 -0.045
    declared and nothing else missing, that bias put the arm camera's residual 1.4 times
    its floor)."""
    lens = (K, dist) if K is not None and dist is not None and np.any(dist) else (None, None)
    return np.asarray(det.corners_for(*lens), float).reshape(-1, 2)


@dataclass(frozen=True)
class ArmView:
    """One photo: commanded joints ``q_deg`` (2,), ``j4_deg``, marker corners in sheet mm
    ``corners_mm`` (N, 2) and where they were seen ``corners_px`` (N, 2); ``det`` the
    measurement's detections it came from (the markers' borders), kept to find the
    corners again in another lens (:meth:`in_lens`)."""

    file: str
    q_deg: np.ndarray
    j4_deg: float
    corners_mm: np.ndarray
    corners_px: np.ndarray
    approach: tuple[float, float] = (1.0, 1.0)   # each joint's last motion sign
    det: ImageDetections | None = None

    def in_lens(self, K, dist) -> "ArmView":
        """The view with its corners found again in the lens ``(K, dist)``
        (:func:`lens_corners`); as it is without its detections."""
        if self.det is None:
            return self
        return replace(self, corners_px=lens_corners(self.det, K, dist))


@dataclass(frozen=True)
class ArmFit:
    """``params`` the robot; ``T_flange_camera`` (4, 4); ``cov`` (P, P) in :attr:`labels`
    units (the 12 of :data:`LABELS`, any backlash, an estimated lens's (f, k1, k2));
    ``rms_px`` the corner reprojection RMS, ``view_rms_px`` (N,)."""

    params: ScaraParams
    T_flange_camera: np.ndarray
    cov: np.ndarray
    rms_px: float
    view_rms_px: np.ndarray
    n_corners: int
    pose_rms: dict | None = None     # per-photo flange pose scatter (mm, deg) by component
    #: the noise floor's inputs (:func:`_floor_terms`): per photo the in-plane residual of
    #: the flange position (N, 2) mm, the per-axis std the corner noise alone gives it (N,),
    #: its leave-one-photo-out residual (N, 2) and the parameters those rows consume
    flange_residual_mm: np.ndarray | None = None
    flange_sigma_mm: np.ndarray | None = None
    flange_heldout_mm: np.ndarray | None = None
    n_params_xy: float = 0.0
    corner_sigma_px: float = float("nan")
    #: per photo the variance factor of its leave-one-out residual, 1 / (1 - leverage)
    #: (averaged over x and y): a photo the fit leans on is predicted less well without it
    flange_heldout_inflate: np.ndarray | None = None
    #: joints (1, 2) whose backlash was fitted: parameters 12, 13 ... (full band, deg)
    backlash_joints: tuple[int, ...] = ()
    backlash_band_deg: tuple[float, ...] = ()
    #: an estimated lens's parameters (:data:`LENS_LABELS`) last in ``cov``: the fit's
    #: covariance with the lens's carried through it (the camera's height trades with the
    #: focal length); ``cov_given_lens`` the fit's own, the lens held (P, P)
    lens_labels: tuple[str, ...] = ()
    cov_given_lens: np.ndarray | None = None

    @property
    def labels(self) -> tuple[str, ...]:
        return (LABELS + tuple(f"backlash{j}_deg" for j in self.backlash_joints)
                + self.lens_labels)

    @property
    def backlash_deg(self) -> dict[int, float]:
        return dict(zip(self.backlash_joints, self.backlash_band_deg))

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov), 0.0, None))

    @property
    def not_identifiable(self) -> list[str]:
        """The robot's and the mount's parameters (not the lens's) whose std is above
        :data:`UNIDENTIFIED_STD` (mm or deg)."""
        return [lab for lab, s in zip(self.labels, self.std)
                if lab not in self.lens_labels and not s < UNIDENTIFIED_STD]

    @property
    def not_identifiable_given_lens(self) -> list[str]:
        """:attr:`not_identifiable` with the lens held: what the poses leave undetermined
        whatever the lens (the rest is the lens's: its focal length moves the height)."""
        if self.cov_given_lens is None:
            return self.not_identifiable
        sd = np.sqrt(np.clip(np.diag(self.cov_given_lens), 0.0, None))
        return [lab for lab, s in zip(self.labels, sd) if not s < UNIDENTIFIED_STD]

    def high_correlations(self, limit: float = 0.9) -> list[dict]:
        """Pairs of parameters whose correlation is above ``limit`` in size."""
        sd = self.std
        with np.errstate(invalid="ignore", divide="ignore"):
            c = self.cov / np.outer(sd, sd)
        lab = self.labels
        return [{"a": lab[i], "b": lab[j], "r": float(c[i, j])}
                for i in range(len(lab)) for j in range(i + 1, len(lab))
                if np.isfinite(c[i, j]) and abs(c[i, j]) > limit]

    def to_json(self) -> dict:
        sd = self.std
        return {"params": self.params.to_json(),
                "std": {"L1_mm": sd[0], "L2_mm": sd[1], "joint_zero_deg": [sd[2], sd[3]],
                        "base_mm": [sd[4], sd[5]]},
                "T_flange_camera": self.T_flange_camera.tolist(),
                "T_flange_camera_std": {"rotation_deg": sd[6:9].tolist(),
                                        "translation_mm": sd[9:12].tolist()},
                "covariance": {"params": list(self.labels), "matrix": self.cov.tolist()},
                "effects": [{"name": "joint_backlash", "joint": j, "deg": d,
                             "std": float(sd[12 + k])}
                            for k, (j, d) in enumerate(self.backlash_deg.items())],
                "corner_rms_px": self.rms_px, "n_corners": self.n_corners,
                "pose_rms": self.pose_rms,
                "not_identifiable": self.not_identifiable,
                "identifiability": {"n_params": len(self.labels), "labels": list(self.labels),
                                    "high_correlations": self.high_correlations()}}


@dataclass(frozen=True)
class _LensInfo:
    """What the views say about a lens's (f px, k1, k2) at a ``calibrateCamera``
    solution, every view's pose profiled out (Schur complement): ``cov`` (3, 3) the
    residuals' own (scaled by their pooled variance), ``cov_robust`` the same clustered by
    photo (the sandwich: a photo's corners share its blur, its print and its view, so their
    errors are not independent, and a rendered series put the focal length 3 of its own
    std off), the larger of the two along the focal length; ``s2_view`` the median view's
    residual variance (px^2 per axis: the corners' noise)."""

    cov: np.ndarray
    cov_robust: np.ndarray
    s2_view: float


def _lens_info(obj, img, K, dist, rvecs, tvecs) -> _LensInfo:
    """:class:`_LensInfo` of views ``obj`` (sheet mm) seen at ``img`` (px) with the lens
    ``(K, dist)`` and the views' poses ``rvecs``, ``tvecs``: the one covariance policy
    (:func:`vision_cal.model.solve.covariance`) on the lens's Jacobian with each view's
    pose projected out of its rows (the Schur complement's Gram), the residuals' variance
    pooled, and clustered by photo (the sandwich of the views' scores)."""
    rows, scores, per_view = [], [], []
    ssr, n_rows = 0.0, 0
    for o, m, rv, tv in zip(obj, img, rvecs, tvecs):
        uv, J = cv2.projectPoints(o.reshape(-1, 1, 3).astype(np.float64), rv, tv, K, dist)
        r = (uv.reshape(-1, 2) - m.reshape(-1, 2)).ravel()
        ssr += float(r @ r)
        n_rows += len(r)
        per_view.append(float(r @ r) / max(len(r) - 6, 1))
        A = np.column_stack([J[:, 6] + J[:, 7], J[:, 10], J[:, 11]])   # f, k1, k2
        B = J[:, :6]                                                    # rvec, tvec
        Ap = A - B @ np.linalg.lstsq(B, A, rcond=None)[0]               # the pose profiled out
        rows.append(Ap)
        scores.append(Ap.T @ r)
    n = len(scores)
    s2 = ssr / max(n_rows - 6 * n - 3, 1)
    s2_view = float(np.median(per_view)) if per_view else s2
    Jp = np.vstack(rows)
    lens = covariance(Jp, labels=LENS_LABELS, s2=s2)
    if lens.not_fixed:
        inf = np.full((3, 3), np.inf)
        return _LensInfo(inf, inf, s2_view)
    g = np.array(scores)
    sandwich = covariance(Jp, meat=g.T @ g).matrix * n / max(n - 3, 1)
    model = lens.matrix
    inflate = max(1.0, float(sandwich[0, 0] / model[0, 0])) if model[0, 0] > 0 else 1.0
    return _LensInfo(model, model * inflate, s2_view)


#: the lens parameters whose covariance an estimated lens carries into the arm camera's
#: (calibration.json ``covariance``, after the robot's and the mount's)
LENS_LABELS = ("f_px", "k1", "k2")


@dataclass(frozen=True)
class Lens:
    """The arm camera's lens estimated from its views: ``K`` (3, 3), ``dist`` (5,), how
    (``estimated`` or :data:`~vision_cal.camera.fixed.UNDETERMINED`), ``f_px_std``, and
    ``cov`` (3, 3) over :data:`LENS_LABELS` (clustered by photo; None: undetermined)."""

    K: np.ndarray
    dist: np.ndarray
    intrinsics: str
    f_px_std: float
    reason: str = ""
    cov: np.ndarray | None = None


def estimate_lens(views: list["ArmView"], size_px) -> Lens:
    """The lens from the views' marker corners when session.json declares none: OpenCV's
    ``calibrateCamera`` (Zhang's method) with the principal point at the image centre and
    square pixels, focal length, k1 and k2 fitted.

    A SCARA turns its camera about the sheet's normal only, so every view sees the sheet
    under the same tilt: the views add no new constraint on the lens (parallel planes,
    Zhang's degenerate case) beyond what one view's tilt gives. A camera looking square
    at the sheet therefore cannot tell its focal length from its height: then (std above
    ``F_REL_STD_MAX`` of itself) ``UNDETERMINED``, the focal length set to 1.2 times the
    image's larger side, and only the sheet's plane can be located."""
    w, h = (int(v) for v in size_px)
    f0 = 1.2 * max(w, h)
    K0 = np.array([[f0, 0, (w - 1) / 2], [0, f0, (h - 1) / 2], [0, 0, 1.0]])
    obj = [np.column_stack([v.corners_mm, np.zeros(len(v.corners_mm))]).astype(np.float32)
           for v in views]
    img = [np.asarray(v.corners_px, np.float32).reshape(-1, 1, 2) for v in views]
    flags = (cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_PRINCIPAL_POINT
             | cv2.CALIB_FIX_ASPECT_RATIO | cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3)
    try:
        out = cv2.calibrateCameraExtended(obj, img, (w, h), K0.copy(), np.zeros(5), flags=flags)
    except cv2.error as e:
        raise CalibrationError(f"the lens could not be estimated from the views: {e}") from e
    K, dist = out[1], np.asarray(out[2], float).ravel()[:5]
    info = _lens_info(obj, img, K, dist, out[3], out[4])
    f_sd = float(np.sqrt(info.cov_robust[0, 0])) if np.isfinite(info.cov_robust[0, 0]) \
        else float("inf")
    if K[0, 0] > 0 and f_sd < F_REL_STD_MAX * K[0, 0]:
        return Lens(np.asarray(K, float), dist, "estimated", f_sd, cov=info.cov_robust)
    # f free trades with the height: keep the plane's mapping, distortion with f fixed
    out = cv2.calibrateCameraExtended(obj, img, (w, h), K0.copy(), np.zeros(5),
                                      flags=flags | cv2.CALIB_FIX_FOCAL_LENGTH)
    Ku, du = np.asarray(out[1], float), np.asarray(out[2], float).ravel()[:5]
    return Lens(Ku, du, UNDETERMINED, f_sd if np.isfinite(f_sd) else float("inf"),
                f"the lens was not declared and the views (all at the same tilt to the sheet, "
                f"{f_sd / max(K[0, 0], 1e-9):.0%} relative std of the focal length) cannot "
                "tell its focal length from the camera's height: T_flange_camera's z and "
                "heights off the sheet's plane are unknown (the robot and the sheet's plane "
                "are not affected); declare camera K in session.json, or tilt the camera "
                "15 deg or more",
                _capped(_lens_info(obj, img, Ku, du, out[3], out[4]).cov_robust,
                        UNDETERMINED_F_REL * Ku[0, 0]))


#: an undetermined focal length's std is carried as this share of itself at most (its
#: trade with the height is what matters: the sheet's plane stays where the views put it)
UNDETERMINED_F_REL = 0.5


def _capped(cov: np.ndarray, f_sd_max: float) -> np.ndarray:
    """``cov`` over (f, k1, k2) with the focal length's std at most ``f_sd_max`` (its
    correlations kept); an infinite or undefined one is that with no correlation."""
    cov = np.array(cov, float)
    if not np.all(np.isfinite(cov)):
        out = np.zeros((3, 3))
        out[0, 0] = f_sd_max**2
        return out
    sd = np.sqrt(max(cov[0, 0], 0.0))
    if sd > f_sd_max:
        c = f_sd_max / sd
        cov[0, :] *= c
        cov[:, 0] *= c
    return cov


@dataclass(frozen=True)
class LensCheck:
    """A declared lens against what the views measure (:func:`check_declared_lens`).

    ``f_views_px`` and ``f_std_px``: the focal length the views give with the declared
    principal point (NaN std: the views cannot tell it from the camera's height);
    ``f_sigmas``: declared minus views in their std; ``dist_px``: how much further the
    declared distortion moves the farthest corner seen than the views' (k1, k2), with
    ``dist_std_px``; ``corner_sigma_px``: the corners' noise per axis with the views' own
    lens (what the detector does, whatever the declaration); ``reasons``: (status,
    sentence) when the views contradict the declaration."""

    f_declared_px: float
    f_views_px: float
    f_std_px: float
    f_sigmas: float
    dist_px: float
    dist_std_px: float
    corner_sigma_px: float
    reasons: tuple[tuple[str, str], ...] = ()

    def to_json(self) -> dict:
        def num(x):
            return float(x) if np.isfinite(x) else None
        return {"f_declared_px": num(self.f_declared_px), "f_views_px": num(self.f_views_px),
                "f_std_px": num(self.f_std_px), "f_sigmas": num(self.f_sigmas),
                "distortion_difference_px": num(self.dist_px),
                "distortion_difference_std_px": num(self.dist_std_px),
                "corner_sigma_px": num(self.corner_sigma_px),
                "contradicted": bool(self.reasons)}


_FIX_HIGHER = (cv2.CALIB_FIX_K3 | cv2.CALIB_FIX_K4 | cv2.CALIB_FIX_K5 | cv2.CALIB_FIX_K6
               | cv2.CALIB_FIX_S1_S2_S3_S4 | cv2.CALIB_FIX_TAUX_TAUY)


def check_declared_lens(views: list["ArmView"], size_px, K, dist,
                        config: VerdictConfig | None = None) -> LensCheck:
    """The declared lens (``K``, ``dist``) against the views' own: ``calibrateCamera`` from
    the declared lens with its principal point and aspect held, the focal length, k1 and
    k2 free (the declared higher terms held), their covariance with every view's pose
    profiled out. The declaration is contradicted (``not reliable``) when its focal length
    is more than ``config.lens_sigma`` std *and* ``config.lens_min_f_rel`` of itself from
    the views', or its distortion moves the farthest corner seen more than ``lens_sigma``
    std *and* ``lens_min_px`` from where the views' does. When the views cannot tell the
    focal length (all at one tilt, nearly square to the sheet: std above
    ``F_REL_STD_MAX``), the distortion is compared at the declared focal length."""
    cfg = config or DEFAULT.verdict
    w, h = (int(v) for v in size_px)
    K = np.asarray(K, float)
    d = np.asarray(dist, float).ravel()
    d_full = np.zeros(max(len(d), 5))
    d_full[:len(d)] = d
    obj = [np.column_stack([v.corners_mm, np.zeros(len(v.corners_mm))]).astype(np.float32)
           for v in views]
    img = [np.asarray(v.corners_px, np.float32).reshape(-1, 1, 2) for v in views]
    flags = (cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_PRINCIPAL_POINT
             | cv2.CALIB_FIX_ASPECT_RATIO | cv2.CALIB_FIX_TANGENT_DIST | _FIX_HIGHER)
    if len(d_full) >= 8:
        flags |= cv2.CALIB_RATIONAL_MODEL
    if len(d_full) >= 12:
        flags |= cv2.CALIB_THIN_PRISM_MODEL
    if len(d_full) >= 14:
        flags |= cv2.CALIB_TILTED_MODEL
    d0 = d_full.copy()

    def calibrate(extra):
        try:
            out = cv2.calibrateCameraExtended(obj, img, (w, h), K.copy(), d0.copy(),
                                              flags=flags | extra)
        except cv2.error as e:
            raise CalibrationError(f"the declared lens could not be checked against the "
                                   f"views: {e}") from e
        Kv, dv = np.asarray(out[1], float), np.asarray(out[2], float).ravel()
        info = _lens_info(obj, img, Kv, dv, out[3], out[4])
        return Kv, dv, info.cov_robust, info.s2_view

    Kv, dv, cov, s2 = calibrate(0)
    f_v, f_sd = float(Kv[0, 0]), float(np.sqrt(max(cov[0, 0], 0.0)))
    f_known = np.isfinite(f_sd) and 0 < f_sd < F_REL_STD_MAX * f_v
    if not f_known:   # the views cannot tell f: compare the distortion at the declared f
        Kv, dv, cov, s2 = calibrate(cv2.CALIB_FIX_FOCAL_LENGTH)
        f_sd = float("nan")
    f_d = float(K[0, 0])
    z_f = (f_d - f_v) / f_sd if f_known else float("nan")
    # the farthest corner seen, normalised by the focal length, and the radial displacement
    # there: f (k1 r^3 + k2 r^5)
    c = np.array([K[0, 2], K[1, 2]])
    r_px = max(float(np.max(np.hypot(*(np.asarray(v.corners_px) - c).T))) for v in views)
    rn = r_px / f_d
    g = f_d * np.array([rn**3, rn**5])
    dd = float(g @ (d_full[:2] - dv[:2]))
    ck = cov[1:, 1:] if f_known else _lens_cov_k(cov)
    dd_sd = float(np.sqrt(max(g @ ck @ g, 0.0)))
    reasons = []
    if f_known and abs(z_f) > cfg.lens_sigma and abs(f_d - f_v) > cfg.lens_min_f_rel * f_v:
        reasons.append(("not reliable",
                        f"the declared lens disagrees with the views: its focal length "
                        f"{f_d:.1f} px, the views measure {f_v:.1f} +- {f_sd:.1f} px "
                        f"({abs(z_f):.0f} std, {100 * (f_d / f_v - 1):+.1f} %): heights and "
                        "T_flange_camera's z scale with it; declare the lens the views "
                        "measure or calibrate the lens again"))
    if (dd_sd > 0 and abs(dd) > cfg.lens_sigma * dd_sd and abs(dd) > cfg.lens_min_px) or (
            dd_sd == 0 and abs(dd) > cfg.lens_min_px):
        reasons.append(("not reliable",
                        f"the declared lens's distortion disagrees with the views: at the "
                        f"farthest corner seen ({r_px:.0f} px from the centre) it moves the "
                        f"image {dd:+.2f} px more than the views' (k1 {dv[0]:.4f}, k2 "
                        f"{dv[1]:.4f} against the declared {d_full[0]:.4f}, {d_full[1]:.4f}; "
                        + (f"{abs(dd) / dd_sd:.0f} std" if dd_sd > 0 else "exact")
                        + "): declare the lens's distortion"))
    return LensCheck(f_d, f_v, f_sd, z_f, dd, dd_sd, float(np.sqrt(s2)), tuple(reasons))


def _lens_cov_k(cov: np.ndarray) -> np.ndarray:
    """(k1, k2) covariance of a fit with the focal length held: the (f, k1, k2) covariance
    conditioned on f (its information matrix without f's row and column)."""
    try:
        info = np.linalg.inv(cov)
    except np.linalg.LinAlgError:
        return np.full((2, 2), np.inf)
    try:
        return np.linalg.inv(info[1:, 1:])
    except np.linalg.LinAlgError:
        return np.full((2, 2), np.inf)


def T_sheet_flange(params: ScaraParams, q_deg, j4_deg) -> np.ndarray:
    """(N, 4, 4) flange -> sheet for commanded joints (N, 2) and ``j4_deg`` (N,): the flange
    x axis turned by ``phi1 + phi2`` (the estimator's one owner,
    :func:`vision_cal.model.kinematics.flange_angle_rad`) plus ``q4`` (the contract's flange frame:
    x along link 2 at commanded ``q4 = 0``)."""
    q = np.array(q_deg, dtype=float, ndmin=2)
    a = (flange_angle_rad(params.vector, np.radians(q[:, :2]))
         + np.radians(np.asarray(j4_deg, float).ravel()))
    p = forward(params, q)
    T = np.tile(np.eye(4), (len(q), 1, 1))
    T[:, 0, 0], T[:, 0, 1], T[:, 1, 0], T[:, 1, 1] = np.cos(a), -np.sin(a), np.sin(a), np.cos(a)
    T[:, :2, 3] = p
    return T


def _unpack(x: np.ndarray, R0: np.ndarray) -> tuple[ScaraParams, np.ndarray]:
    """Robot and T_flange_camera; the camera's rotation is a small turn (deg, about the
    flange axes) of ``R0`` (the start), so the parameters stay far from any singularity."""
    p = ScaraParams(x[0], x[1], x[2], x[3], x[4], x[5])
    X = homogeneous(cv2.Rodrigues(np.radians(x[6:9]).reshape(3, 1))[0] @ R0, x[9:12])
    return p, X


def _link_commands(x, views, bl) -> np.ndarray:
    """(N, 2) commands with the fitted backlash of joints ``bl`` applied (the contract's
    ``joint_backlash``: the joint lags by ``-s band / 2`` against its approach ``s``)."""
    q = np.array([v.q_deg for v in views], float).reshape(-1, 2)
    for k, j in enumerate(bl):
        s = np.array([v.approach[j - 1] for v in views], float)
        q[:, j - 1] -= s * x[12 + k] / 2.0
    return q


def _solved(residual, x0, what: str):
    """The one solver (:func:`vision_cal.model.solve.solve`: Levenberg-Marquardt, the
    parameters scaled by the Jacobian's columns, scipy's default tolerances) on ``residual``
    from ``x0``; a solve stopped on its limit ends the calibration with the reason."""
    sol = solve(residual, x0, method="lm", x_scale="jac", xtol=1e-8, ftol=1e-8, gtol=1e-8)
    if not sol:
        raise CalibrationError(f"the arm camera's {what} did not converge: {sol.reason}")
    return sol


def _residuals(x, views, K, dist, R0, bl=()) -> np.ndarray:
    p, X = _unpack(x, R0)
    T_sc = T_sheet_flange(p, _link_commands(x, views, bl), [v.j4_deg for v in views]) @ X
    out = []
    for v, T in zip(views, T_sc):
        T_cs = np.linalg.inv(T)
        rvec = cv2.Rodrigues(T_cs[:3, :3])[0]
        obj = np.column_stack([v.corners_mm, np.zeros(len(v.corners_mm))])
        uv, _ = cv2.projectPoints(obj.reshape(-1, 1, 3), rvec, T_cs[:3, 3], K, dist)
        out.append((uv.reshape(-1, 2) - v.corners_px).ravel())
    return np.concatenate(out)


#: a marker whose corners sit further from its photo's own pose fit than this many times
#: the photo's corner noise ...
MARKER_OUTLIER_SIGMA = 8.0
#: ... and than this (px) is misdetected (cut by the image's edge or a reflection)
MARKER_OUTLIER_PX = 0.5
#: never more than this share of a photo's markers is left out (a wrong lens bends them all)
MARKER_OUTLIER_SHARE = 0.25


def without_misdetected(views: list[ArmView], K, dist) -> tuple[list[ArmView], dict]:
    """Each photo's markers found pixels off left out, worst first: a marker whose corners'
    RMS distance from the photo's own pose fit (PnP through ``(K, dist)``, the others
    holding it) is beyond :data:`MARKER_OUTLIER_SIGMA` times the photo's corner noise (the
    median corner's, Rayleigh) and :data:`MARKER_OUTLIER_PX`, at most
    :data:`MARKER_OUTLIER_SHARE` of them. A marker cut by the image's edge, or by a
    reflection, is found with corners 5-15 px off in a photo whose corners are 0.03 px
    good; kept, its photo's flange would read as the robot's. Returns the views and, per
    photo with markers left out, how many."""
    out, dropped = [], {}
    for v in views:
        keep = np.ones(len(v.corners_mm) // 4, bool)
        for _ in range(int(MARKER_OUTLIER_SHARE * len(keep))):
            idx = np.repeat(keep, 4)
            obj = np.column_stack([v.corners_mm[idx], np.zeros(int(idx.sum()))])
            ok, rvec, tvec = cv2.solvePnP(obj.reshape(-1, 1, 3),
                                          v.corners_px[idx].reshape(-1, 1, 2), K, dist,
                                          flags=cv2.SOLVEPNP_ITERATIVE)
            if not ok:
                break
            obj_all = np.column_stack([v.corners_mm, np.zeros(len(v.corners_mm))])
            uv = cv2.projectPoints(obj_all.reshape(-1, 1, 3), rvec, tvec, K, dist)[0]
            r = np.linalg.norm(uv.reshape(-1, 2) - v.corners_px, axis=1)
            sigma = float(np.median(r[idx])) / 1.1774        # a 2-D normal's median radius
            per = np.sqrt(np.mean(r.reshape(-1, 4) ** 2, axis=1))
            per[~keep] = -1.0
            worst = int(np.argmax(per))
            if per[worst] <= max(MARKER_OUTLIER_SIGMA * sigma, MARKER_OUTLIER_PX):
                break
            keep[worst] = False
        if keep.all():
            out.append(v)
            continue
        idx = np.repeat(keep, 4)
        dropped[v.file] = int((~keep).sum())
        out.append(replace(v, corners_mm=v.corners_mm[idx], corners_px=v.corners_px[idx],
                           det=None if v.det is None else v.det.keep_markers(keep)))
    return out, dropped


def camera_pose(view: ArmView, K, dist) -> np.ndarray:
    """T_sheet_camera (4, 4) of one photo from its corners alone."""
    obj = np.column_stack([view.corners_mm, np.zeros(len(view.corners_mm))])
    ok, rvec, tvec = cv2.solvePnP(obj.reshape(-1, 1, 3), view.corners_px.reshape(-1, 1, 2),
                                  K, dist, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise CalibrationError(f"{view.file}: no camera pose from its markers")
    return np.linalg.inv(homogeneous(cv2.Rodrigues(rvec)[0], tvec))


def fit_arm_camera(views: list[ArmView], K, dist, nominal: ScaraParams, *,
                   corner_sigma_px: float | None = None,
                   lens_cov: np.ndarray | None = None) -> ArmFit:
    """Robot and ``T_flange_camera`` from photos taken by the arm's camera.

        fit = fit_arm_camera(views, K, dist, session.robot.params)   # fit.params, fit.cov

    ``K``, ``dist``: the lens (declared, or :func:`estimate_lens`'s); it starts from
    ``nominal`` and the first photo's pose. A joint reached from
    both sides in the photos (their ``approach``) has its backlash fitted as well (the
    contract's ``joint_backlash``; from one side only it is part of the joint's zero).

    ``corner_sigma_px``: the corners' noise (px, per axis) the noise floor is built from,
    what the detector does (the views' own lens: :func:`check_declared_lens`); None: the
    photos' own pose fits with ``K`` and ``dist`` (a wrong declared lens then inflates it
    and hides itself). ``lens_cov`` (3, 3): an estimated lens's covariance over
    :data:`LENS_LABELS`, carried into the parameters' (:func:`_with_lens`)."""
    bl = tuple(j for j in (1, 2) if len({v.approach[j - 1] for v in views}) > 1)
    if len(views) < MIN_POSES:
        raise CalibrationError(f"{len(views)} usable photos: at least {MIN_POSES} are needed "
                               "(12 parameters, and each kind of pose residual needs its own "
                               "degrees of freedom for its variance)")
    K = np.asarray(K, float)
    dist = np.zeros(5) if dist is None else np.asarray(dist, float)
    T0 = camera_pose(views[0], K, dist)
    X0 = np.linalg.inv(T_sheet_flange(nominal, [views[0].q_deg], [views[0].j4_deg])[0]) @ T0
    x0 = np.concatenate([[nominal.L1_mm, nominal.L2_mm, nominal.z1_deg, nominal.z2_deg,
                          nominal.base_x_mm, nominal.base_y_mm],
                         np.zeros(3), X0[:3, 3], np.zeros(len(bl))])
    R0 = X0[:3, :3]
    sol = _solved(lambda x: _residuals(x, views, K, dist, R0, bl), x0, "fit to the corners")
    # again about the solution, so the rotation's covariance is about the found frame
    p1, X1 = _unpack(sol.x, R0)
    R0 = X1[:3, :3]
    x1 = np.concatenate([sol.x[:6], np.zeros(3), sol.x[9:]])
    sol = _solved(lambda x: _residuals(x, views, K, dist, R0, bl), x1, "fit to the corners")
    r = sol.residuals
    n = len(r)
    p, X = _unpack(sol.x, R0)
    sizes = np.cumsum([0] + [2 * len(v.corners_mm) for v in views])
    view_rms = np.array([rms_2d(r[a:b].reshape(-1, 2)) for a, b in zip(sizes[:-1], sizes[1:])])
    # the std: at the photo level. The robot's repeatability moves a whole photo, so corner
    # residuals are not independent; the flange pose each photo implies, against the
    # model's, is (one 6-vector per photo), with each kind of component's variance found
    # from its own scatter
    M, C_pnp, sigma_px = _view_poses(views, K, dist)
    if corner_sigma_px is not None and np.isfinite(corner_sigma_px) and corner_sigma_px > 0:
        C_pnp = C_pnp * (corner_sigma_px / max(sigma_px, 1e-12)) ** 2
        sigma_px = float(corner_sigma_px)
    x2 = np.concatenate([sol.x[:6], np.zeros(3), sol.x[9:]])
    x3, cov, rms_pose, lev, jac, w = _pose_level_fit(x2, views, M, R0, bl)
    p, X = _unpack(x3, R0)          # the estimate the covariance belongs to
    e = _pose_residuals(x3, views, M, R0, bl)
    sig = _floor_terms(x3, views, M, C_pnp, R0, bl)
    keep = np.clip(1.0 - lev[:, :2], 1e-3, None)
    held = e[:, :2] / keep
    lens = {}
    if lens_cov is not None:
        lens = {"cov": _with_lens(cov, lens_cov, _lens_sensitivity(
                    x3, views, M, R0, bl, K, dist, jac, w)),
                "lens_labels": LENS_LABELS, "cov_given_lens": cov}
    return ArmFit(p, X, lens.get("cov", cov), rms_2d(r.reshape(-1, 2)), view_rms, n // 2,
                  rms_pose, e[:, :2].copy(), sig, held, float(lev[:, :2].sum()), sigma_px,
                  np.mean(1.0 / keep, axis=1), bl, tuple(float(v) for v in x3[12:]),
                  lens.get("lens_labels", ()), lens.get("cov_given_lens"))


def _lens_sensitivity(x, views, M, R0, bl, K, dist, jac, w) -> np.ndarray:
    """(P, 3) how the photo-level fit's parameters move with the lens's (f px, k1, k2):
    each photo's pose solved again with the lens moved (PnP from its own pose), the fit's
    weighted pose residuals moved with it, the Gauss-Newton step they ask for
    (``-(J^T J)^-1 J^T de``, ``jac`` the weighted Jacobian at ``x``, ``w`` the weights)."""
    K = np.asarray(K, float)
    d0 = np.zeros(max(5, len(np.ravel(dist))))
    d0[:len(np.ravel(dist))] = np.ravel(dist)
    steps = (1e-3 * K[0, 0], 1e-4, 1e-4)
    G = np.zeros((len(x), 3))
    for j, h in enumerate(steps):
        e = []
        for sgn in (1.0, -1.0):
            Kj, dj = K.copy(), d0.copy()
            if j == 0:
                Kj[0, 0] += sgn * h
                Kj[1, 1] += sgn * h
            else:
                dj[j - 1] += sgn * h
            Mj = np.array([_pnp_again(v, Mi, Kj, dj) for v, Mi in zip(views, M)])
            e.append((_pose_residuals(x, views, Mj, R0, bl) * w).ravel())
        G[:, j] = -np.linalg.lstsq(jac, (e[0] - e[1]) / (2 * h), rcond=None)[0]
    return G


def _pnp_again(view: ArmView, T_sheet_camera: np.ndarray, K, dist) -> np.ndarray:
    """The photo's ``T_sheet_camera`` solved again with the lens ``(K, dist)``, from its
    pose ``T_sheet_camera``."""
    T_cs = np.linalg.inv(T_sheet_camera)
    obj = np.column_stack([view.corners_mm, np.zeros(len(view.corners_mm))])
    _, rvec, tvec = cv2.solvePnP(obj.reshape(-1, 1, 3), view.corners_px.reshape(-1, 1, 2),
                                 K, dist, cv2.Rodrigues(T_cs[:3, :3])[0], T_cs[:3, 3].copy(),
                                 useExtrinsicGuess=True, flags=cv2.SOLVEPNP_ITERATIVE)
    return np.linalg.inv(homogeneous(cv2.Rodrigues(rvec)[0], tvec))


def _with_lens(cov: np.ndarray, lens_cov: np.ndarray, G: np.ndarray) -> np.ndarray:
    """The (P + 3) covariance of the parameters and the lens: the fit's ``cov`` (the lens
    held) plus the lens's carried through the sensitivity ``G`` (P, 3), and their cross
    terms (the two errors independent: the lens from the corners' shape within each photo,
    the fit from where the photos stand)."""
    P = len(cov)
    out = np.zeros((P + 3, P + 3))
    out[:P, :P] = cov + G @ lens_cov @ G.T
    out[:P, P:] = G @ lens_cov
    out[P:, :P] = out[:P, P:].T
    out[P:, P:] = lens_cov
    return out


def _view_poses(views, K, dist) -> tuple[np.ndarray, np.ndarray, float]:
    """Per photo ``T_sheet_camera`` from its corners alone (N, 4, 4), the covariance (N, 6, 6)
    of its ``T_camera_sheet`` (rotation vector rad, translation mm) from the corner noise,
    and that noise (px, per axis): the median photo's (each photo's own pose fit leaves
    the corner noise alone, robot-free), so one photo's few corners do not make its own
    figure, and one bad photo (a corner 2.5 px off in a rendered series) does not raise
    every photo's floor tenfold and hide what the others show."""
    T, C, s2s = [], [], []
    for v in views:
        T_cs, _, cov, rms = fit_pose(v.corners_mm, v.corners_px, K, dist, free_f=False)
        n = len(v.corners_mm)
        s2 = rms**2 * n / max(2 * n - 6, 1)
        T.append(np.linalg.inv(T_cs))
        C.append(cov[:6, :6] / max(s2, 1e-30))
        s2s.append(s2)
    s2 = float(np.median(s2s))
    return np.array(T), np.array(C) * s2, float(np.sqrt(s2))


def _floor_terms(x, views, M, C_pnp, R0, bl=()) -> np.ndarray:
    """(N,) per-axis std of each photo's in-plane flange residual that the corner noise
    alone gives: its pose covariance ``C_pnp`` carried through the residual (the camera's
    tilt error times its height above the flange is in it)."""
    out = np.empty(len(views))
    for i, v in enumerate(views):
        T_cs = np.linalg.inv(M[i])
        p0 = np.concatenate([cv2.Rodrigues(T_cs[:3, :3])[0].ravel(), T_cs[:3, 3]])
        J = np.empty((2, 6))
        for k in range(6):
            step = 1e-6 if k < 3 else 1e-4
            rows = []
            for sgn in (1.0, -1.0):
                pk = p0.copy()
                pk[k] += sgn * step
                Mk = np.linalg.inv(homogeneous(cv2.Rodrigues(pk[:3].reshape(3, 1))[0], pk[3:]))
                rows.append(_pose_residuals(x, [v], Mk[None], R0, bl)[0, :2])
            J[:, k] = (rows[0] - rows[1]) / (2 * step)
        out[i] = np.sqrt(max(np.trace(J @ C_pnp[i] @ J.T) / 2.0, 0.0))
    return out


def _pose_residuals(x, views, M, R0, bl=()) -> np.ndarray:
    """(N, 6): per photo the flange pose the photo implies (``M_i inv(X)``) in the model's
    flange frame: translation (mm) and small rotation (rad)."""
    p, X = _unpack(x, R0)
    P = T_sheet_flange(p, _link_commands(x, views, bl), [v.j4_deg for v in views])
    Xi = np.linalg.inv(X)
    out = np.empty((len(views), 6))
    for i in range(len(views)):
        D = np.linalg.inv(P[i]) @ M[i] @ Xi
        R = D[:3, :3]
        out[i, :3] = D[:3, 3]
        out[i, 3:] = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return out


#: the pose residual's components whose variances are found separately: in-plane position,
#: height, tilt, turn
_GROUPS = ((0, 1), (2,), (3, 4), (5,))


def _pose_level_fit(x, views, M, R0, bl=()) -> tuple:
    """The parameters refitted on the photo-level residuals with each group's variance as
    its weight, their covariance (12, 12), the RMS of each group (mm, deg), the
    residuals' leverages (N, 6), the weighted Jacobian (6N, P) and the weights (6,)."""
    w = np.ones(6)
    n, P = len(views), len(x)
    for _ in range(3):
        def f(z):
            return (_pose_residuals(z, views, M, R0, bl) * w).ravel()
        sol = _solved(f, x, "photo-level fit")
        x = sol.x
        e = _pose_residuals(x, views, M, R0, bl)
        var = np.empty(6)
        for g in _GROUPS:
            # each group takes its share of the parameters' degrees of freedom
            dof = max(n * len(g) - P * len(g) / 6.0, 1.0)
            var[list(g)] = max(float(np.sum(e[:, list(g)] ** 2)) / dof, 1e-30)
        w = 1.0 / np.sqrt(var)
    sol = _solved(lambda z: (_pose_residuals(z, views, M, R0, bl) * w).ravel(), x,
                  "photo-level fit")
    # the one policy, the residuals in units of their std: a direction the photos do not
    # fix (L2 against the camera's offset along link 2 without joint-4 turns) is not stated
    cov = covariance(sol.jacobian, s2=1.0).stated
    x = sol.x
    rms = {"position_mm": float(np.sqrt(var[0])), "height_mm": float(np.sqrt(var[2])),
           "tilt_deg": float(np.degrees(np.sqrt(var[3]))),
           "turn_deg": float(np.degrees(np.sqrt(var[5])))}
    # leverages (the hat matrix's diagonal, per residual component): the parameters each
    # row consumes, and a row's leave-one-out residual e / (1 - h)
    J = np.asarray(sol.jacobian)
    Q, _ = np.linalg.qr(J / np.maximum(np.linalg.norm(J, axis=0), 1e-300))
    lev = np.sum(Q**2, axis=1).reshape(n, 6)
    return x, cov, rms, lev, J, w


# --------------------------------------------------------------------------- pixel -> robot

def camera_for(doc: dict, index: int, *, joints_deg=None, photo: str | None = None,
               file: str | None = None) -> FixedCamera:
    """The camera ``cameras[index]`` of a calibration document as it stood for one photo:
    a still camera as is; a camera on the arm at commanded ``joints_deg`` ([q1, q2] or
    [q1, q2, q4], reached with each joint turning counter-clockwise last) or at the command
    and approach of ``photo`` (one of calibration.json's ``poses``); a fitted
    ``joint_backlash`` is applied. ``vision_cal.camera.fixed.locate`` then maps its pixels
    (its std leaves the backlash's own std out)."""
    cams = doc.get("cameras")
    entry = cams[index] if isinstance(cams, list) and 0 <= index < len(cams) else None
    if not isinstance(entry, dict) or "T_flange_camera" not in entry:
        if joints_deg is not None or photo is not None:
            camera_of(doc, index, file=file)       # its own error first, if any
            raise VisionCalError(f"camera {index} stood still: --joints and --photo are for "
                                 "a camera on the arm", file=file,
                                 field="--joints" if joints_deg is not None else "--photo")
        return camera_of(doc, index, file=file)
    where = f"cameras[{index}]"
    # the one validator of a camera block (K, dist, a rotation in mm, the covariance)
    check_camera_entry(entry, where, file or "calibration.json", doc=doc)
    if (joints_deg is None) == (photo is None):
        raise VisionCalError("a camera on the arm: give the arm's command for the photo, "
                             "--joints Q1 Q2 [Q4] or --photo NAME (one of calibration.json "
                             "poses)", file=file, field="--joints")
    if photo is not None:
        pose = next((p for p in doc.get("poses") or [] if p.get("image") == photo), None)
        if pose is None:
            raise VisionCalError(f"no pose named {photo!r} in calibration.json poses",
                                 file=file, field="--photo")
        q, j4 = pose["joints_deg"], float(pose.get("j4_deg", 0.0))
        approach = pose.get("approach") or (1, 1)
    else:
        approach = (1, 1)
        if len(joints_deg) not in (2, 3) or not np.all(np.isfinite(joints_deg)):
            raise VisionCalError("expected Q1 Q2 [Q4], finite degrees", file=file,
                                 field="--joints")
        q, j4 = joints_deg[:2], float(joints_deg[2]) if len(joints_deg) == 3 else 0.0
    if entry.get("mount") == "link2" and j4 != 0.0:
        raise VisionCalError("this camera is on link 2 and does not turn with joint 4: leave "
                             "Q4 out", file=file, field="--joints")
    try:
        params = ScaraParams.from_json(doc["params"])
        X = np.asarray(entry["T_flange_camera"], float).reshape(4, 4)
        K = np.asarray(entry["K"], float).reshape(3, 3)
        dist = np.asarray(entry["dist"], float).ravel()
        size = tuple(int(v) for v in entry["size_px"])
        labels = list(doc["covariance"].get("params") or LABELS)
        full = np.asarray(doc["covariance"]["matrix"], float)
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise VisionCalError(f"expected params, covariance and {where}'s T_flange_camera, K, "
                             "dist, size_px", file=file, field=where) from e
    q = np.array(q[:2], float)
    for e in doc.get("effects") or []:     # a fitted backlash: the joint lags its approach
        if isinstance(e, dict) and e.get("name") == "joint_backlash" and e.get("joint") in (1, 2):
            q[e["joint"] - 1] -= float(approach[e["joint"] - 1]) * float(e["deg"]) / 2.0
    rep = float((doc.get("verdict") or {}).get("repeatability_mm", 0.0))
    # the robot and mount (12), and an estimated lens's (f, k1, k2) where the covariance
    # carries them: the camera's height trades with the focal length (a declared lens is
    # taken as declared; the views' check of it is calibration.json's lens_check)
    idx = [labels.index(lab) for lab in LABELS]
    lens = [labels.index(lab) for lab in LENS_LABELS if lab in labels]
    lens = lens if len(lens) == len(LENS_LABELS) else []
    how = str(entry.get("intrinsics", "declared"))
    cov = full[np.ix_(idx + lens, idx + lens)]
    if lens and how == UNDETERMINED:
        # only the sheet's plane is located, where the focal length's trade with the
        # height is not seen: the covariance given the lens (its terms conditioned away)
        cov = cov[:12, :12] - cov[:12, 12:] @ np.linalg.pinv(cov[12:, 12:]) @ cov[12:, :12]
    return _camera_at(params, X, cov, q, j4, K=K, dist=dist, size=size, rep=rep,
                      f_sd=0.0 if lens else float(entry.get("f_px_std") or 0.0),
                      intrinsics=how, images=tuple(entry.get("images") or ()))


def _camera_at(params: ScaraParams, X, cov_p, q, j4, *, K, dist, size, rep, f_sd, intrinsics,
               images) -> FixedCamera:
    """The arm camera at command (q, j4) as a :class:`FixedCamera`: ``T_robot_camera`` and
    its covariance from the fit's (``cov_p``: the 12 of :data:`LABELS`, then (f px, k1, k2)
    when the lens was estimated), the robot's repeatability ``rep`` added to its in-plane
    place (the arm stands there within it). With the lens's terms the camera's covariance
    is (9, 9): its pose's 6, the focal length and k1, k2, with the cross terms the fit
    gave them (the height moves with the focal length: the sheet's plane stays, a point
    above it does not); without them (7, 7), ``f_sd`` the focal length's std alone (an
    undetermined lens: only the sheet's plane is located)."""
    R0 = X[:3, :3]
    x0 = np.concatenate([[params.L1_mm, params.L2_mm, params.z1_deg, params.z2_deg,
                          params.base_x_mm, params.base_y_mm], np.zeros(3), X[:3, 3]])

    def T_rc(x):
        p, Xk = _unpack(x, R0)
        T_sc = T_sheet_flange(p, [q], [j4])[0] @ Xk
        return np.linalg.inv(T_sheet_robot(p.z1_deg, (p.base_x_mm, p.base_y_mm))) @ T_sc

    T0 = T_rc(x0)
    J = np.zeros((6, 12))
    steps = np.array([1e-4, 1e-4, 1e-6, 1e-6, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6, 1e-4, 1e-4, 1e-4])
    for k in range(12):
        d = np.zeros(12)
        d[k] = steps[k]
        J[:, k] = (pose_delta(T_rc(x0 + d), T0) - pose_delta(T_rc(x0 - d), T0)) / (2 * steps[k])
    s = np.array([np.degrees(1.0)] * 3 + [1.0] * 3)
    Js = J * s[:, None]
    n = 9 if len(cov_p) == 15 else 7
    cov = np.zeros((n, n))
    cov[:6, :6] = Js @ cov_p[:12, :12] @ Js.T
    if n == 9:
        cov[:6, 6:] = Js @ cov_p[:12, 12:]
        cov[6:, :6] = cov[:6, 6:].T
        cov[6:, 6:] = cov_p[12:, 12:]
    elif f_sd > 0:
        cov[6, 6] = f_sd**2
    cov[3, 3] += rep**2
    cov[4, 4] += rep**2
    return FixedCamera(images, size, K, dist, intrinsics, T0, cov, float("nan"), 0,
                       params.z1_deg, (params.base_x_mm, params.base_y_mm), np.eye(2))
