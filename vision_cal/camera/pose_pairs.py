"""Hand-eye of a SCARA from pose pairs another tool measured (``vision-cal handeye --poses``).

Each pair is the flange as the controller reports it, ``A_i = T_robot_flange``, and the
target (a board) as the camera saw it, ``B_i = T_camera_target`` (4x4, mm, the contract's
``T_A_B``: maps frame B to frame A). Two unknown constant transforms close the loop:

    arm mount   (the camera rides on the flange):   A_i   X B_i = Y
                X = T_flange_camera,  Y = T_robot_target  (the board stands still)
    fixed mount (the camera stands, the board rides): A_i^-1 X B_i = Y
                X = T_robot_camera,   Y = T_flange_target

so both are ``A'_i X B_i = Y`` with ``A'_i = A_i`` or ``A_i^-1``, a turn about the robot's
vertical axis and a translation.

What a SCARA's motion cannot see. Every ``A'_i`` turns about z only, so the z row of the
translations reads ``t_X,z - t_Y,z = -t_A'_i,z - (R_X t_B_i)_z`` in every pair: only the
difference of the two heights is seen (Ulrich & Steger, "Hand-eye calibration of SCARA
robots", 2014/2016; HALCON's ``hand_eye_scara_*`` and the ``handeye-4dof`` project report
the same one unidentifiable translation). One height must be given: ``z_mm`` is the
target's origin height in the frame ``Y`` maps to (the robot frame for an arm mount, the
flange frame for a fixed one); without it it is taken as 0 and the camera's height is
reported ``not identifiable`` with the reason.

The start (a 4-DOF closed form, in the spirit of Ulrich & Steger's: rotations about z
first, then a linear system). ``g = R_Y^T z`` and ``h = R_X^T z`` satisfy ``R_B_i g = h`` in
every pair (the robot's z seen from the target and from the camera): the null vector of
the stacked ``[R_B_i, -I]``, up to a sign tried both ways. With ``R_X = Rz(a) R_h`` (``R_h``
turning ``h`` onto z) the rotation left unknown is the angle ``a`` about z, which the
translations fix: the x, y rows ``Rz_i t_X + Rz_i Rz(a) v_i - t_Y = -t_A'_i`` (``v_i =
R_h t_B_i``) are linear in ``(t_X,x, t_X,y, cos a, sin a, t_Y,x, t_Y,y)``.

Then least squares (scipy) on the 11 parameters left (a small rotation about each frame's
axes and the translations, ``t_Y,z`` held), each pair's residual being where it puts the
target: ``A'_i X B_i`` against ``Y``, its translation (mm) and its rotation (deg), seen
from the camera (where a detector's noise is alike from pair to pair) and whitened by the
pairs' own 6x6 scatter (a board pose's depth and tilt errors are not its lateral ones, and
tilt and shift trade), estimated from the residual with what the fit took from each
direction given back (the hat matrix). The parameters' covariance is the fit's, scaled by
``nu / (nu - 7)`` for weights that are the inverse of an estimated covariance (checked
over many seeds by bench/handeye_pairs.py: error / std near 1). Pairs that disagree beyond
the scatter (their deleted translation or rotation residual, per-axis scatter taken
robustly: the median pair first, then the pairs within the level; the level ``3 F(3,
nu)`` at ``handeye.outlier_alpha`` over the pairs) are left out one at a time, worst
first, and named. The result
is a :class:`PairsFit` (frozen), or a :class:`PairsFailed` (falsy, with the reason).

Before the fit (issue 40, :mod:`vision_cal.camera.pairs_checks`): pairs at one flange pose
are one pose; a consensus of random triples' closed forms leaves out the pairs far from
the best one (up to 60 % of them may be wrong), and the closed form of the pairs it keeps
is the start. After it: another reading of the file that agrees far better (a mount, an
inverse, a transpose, degrees for radians), the target's scale against the flange's (two
units), the flange's reach, directions no pair sees (a singular value at round-off: named,
no std) and sizes no mount has are the ``findings``. The cost is linear in the pairs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from vision_cal.camera import pairs_checks as checks
from vision_cal.camera.pairs_geometry import T_of as _T
from vision_cal.camera.pairs_geometry import (closed_form, closed_form_parts, rotmat,
                                              rotvec, yaw_spread_deg)
from vision_cal.config import DEFAULT, HandeyeConfig
from vision_cal.errors import Failure
from vision_cal.model.solve import covariance, solve
from vision_cal.progress import bar

MOUNTS = ("arm", "fixed")
#: the 11 fitted parameters (a small rotation about each frame's own parent axes, then the
#: translations); ``Y``'s z translation is held (see the module docstring)
LABELS = ("X_rot_x_deg", "X_rot_y_deg", "X_rot_z_deg", "X_x_mm", "X_y_mm", "X_z_mm",
          "Y_rot_x_deg", "Y_rot_y_deg", "Y_rot_z_deg", "Y_x_mm", "Y_y_mm")
#: the median of a chi-square with 1 dof: r^2 / sigma^2 of one normal axis
_CHI2_1_MEDIAN = float(stats.chi2.median(1))
#: a scatter below this (mm or deg) is taken as this: exact synthetic pairs
_TINY = 1e-9


@dataclass(frozen=True)
class PosePair:
    """One pair: ``T_robot_flange`` and ``T_camera_target`` (4, 4), mm; ``flange_yaw`` and
    ``target_rvec``: the numbers the file wrote for the flange's yaw and the target's
    rotation vector where it gave them so (None: as matrices), kept to try the readings a
    tool may have meant (:mod:`vision_cal.camera.pairs_checks`)."""

    id: str
    T_robot_flange: np.ndarray
    T_camera_target: np.ndarray
    flange_yaw: float | None = None
    target_rvec: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class PairsFailed(Failure):
    """A hand-eye that cannot be made (falsy), with the reason; reading a
    :class:`PairsFit`'s attribute from it raises with the reason."""

    reason: str


@dataclass(frozen=True)
class PairsFit:
    """The hand-eye of a SCARA from pose pairs (module docstring).

    ``X``: ``T_flange_camera`` (arm) or ``T_robot_camera`` (fixed); ``Y``: ``T_robot_target``
    or ``T_flange_target``; ``cov`` (11, 11) in :data:`LABELS` units; ``residual_mm`` (N, 3)
    and ``residual_deg`` (N, 3) of every pair (outliers included: against the fit without
    them), in ``Y``'s parent frame; ``heldout_mm`` (N, 3): leave-one-pair-out translation
    residuals (outliers: their residual); ``noise_cov``: the inliers' scatter, the 6x6 covariance of
    a pair's residual in the camera frame (mm, deg: a detector's depth and tilt errors are
    not those across the view); ``sigma_xy_mm`` (N,): the per-axis std it gives each pair's
    x, y in ``Y``'s frame; ``n_params_xy``: the parameters the x, y residuals consume."""

    @property
    def sigma_mm(self) -> float:
        """The scatter of a pair's translation, one std per axis (RMS over the axes)."""
        return math.sqrt(float(np.trace(self.noise_cov[:3, :3])) / 3.0)

    @property
    def sigma_deg(self) -> float:
        """The scatter of a pair's rotation, one std per axis (RMS over the axes)."""
        return math.sqrt(float(np.trace(self.noise_cov[3:, 3:])) / 3.0)

    mount: str
    ids: tuple[str, ...]
    X: np.ndarray
    Y: np.ndarray
    cov: np.ndarray
    residual_mm: np.ndarray
    residual_deg: np.ndarray
    heldout_mm: np.ndarray
    inlier: np.ndarray                  # (N,) bool
    noise_cov: np.ndarray               # (6, 6) the pairs' scatter in the camera frame
    sigma_xy_mm: np.ndarray             # (N,) per-axis std of each pair's x, y (Y's frame)
    n_params_xy: float
    z_mm: float                          # the held height of Y's origin
    z_given: bool
    start_X: np.ndarray                  # the closed form's X and Y
    start_Y: np.ndarray
    outlier_reasons: tuple[str, ...] = ()
    not_identifiable: tuple[dict, ...] = ()
    #: (status, sentence) of the checks of the pairs against each other (units,
    #: conventions, degenerate motion, sizes, outliers beyond the share allowed)
    findings: tuple[tuple[str, str], ...] = ()
    #: pairs at a flange pose an earlier pair has (counted once, their target averaged
    #: into it): (id, the first pair's id) each, and their own residuals (R, 3) mm, deg
    repeats: tuple[tuple[str, str], ...] = ()
    repeat_residual_mm: np.ndarray | None = None
    repeat_residual_deg: np.ndarray | None = None
    #: the labels a direction the pairs do not see moves (their std is not stated)
    unseen: tuple[str, ...] = ()
    #: the closed form's scale of the target's translations against the flange's, its std
    scale: float = 1.0
    scale_std: float = float("inf")

    def __bool__(self) -> bool:
        return True

    @property
    def outliers(self) -> tuple[str, ...]:
        return tuple(i for i, ok in zip(self.ids, self.inlier) if not ok)

    def std(self) -> dict:
        """One std of X and Y: ``rotation_deg`` (about the parent frame's axes) and
        ``translation_mm``; the unseen height (X's z when not given) is None."""
        sd = [None if lab in self.unseen else float(v)
              for lab, v in zip(LABELS, np.sqrt(np.clip(np.diag(self.cov), 0.0, None)))]
        x_t = sd[3:6]
        if not self.z_given:
            x_t[2] = None
        return {"X": {"rotation_deg": sd[0:3], "translation_mm": x_t},
                "Y": {"rotation_deg": sd[6:9],
                      "translation_mm": [sd[9], sd[10], 0.0 if self.z_given else None]}}


def flange_tilt_deg(T_robot_flange: np.ndarray) -> float:
    """How far a flange pose's z axis is from the robot's (deg): a SCARA's is 0."""
    return math.degrees(math.acos(np.clip(T_robot_flange[2, 2], -1.0, 1.0)))


def _moving(T: np.ndarray, mount: str) -> np.ndarray:
    """``A'`` (N, 4, 4) of flange poses ``T`` (N, 4, 4): themselves (arm) or their inverse."""
    return T if mount == "arm" else np.linalg.inv(T)


def _unpack(x, X0, Y0, z_mm) -> tuple[np.ndarray, np.ndarray]:
    RX = rotmat(np.radians(x[0:3])) @ X0[:3, :3]
    RY = rotmat(np.radians(x[6:9])) @ Y0[:3, :3]
    return _T(RX, X0[:3, 3] + x[3:6]), _T(RY, [Y0[0, 3] + x[9], Y0[1, 3] + x[10], z_mm])


def _raw_residuals(x, A, B, X0, Y0, z_mm) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where each pair puts the target against ``Y``: (N, 3) mm and (N, 3) deg in ``Y``'s
    parent frame, and (N, 6) the same in the camera frame (mm, deg), where a detector's
    noise is the same in every pair."""
    X, Y = _unpack(x, X0, Y0, z_mm)
    AX = A @ X
    P = AX @ B
    dt = P[:, :3, 3] - Y[:3, 3]
    dR = Y[:3, :3].T @ P[:, :3, :3]
    dr = np.degrees(rotvec(dR))                                # in the target's frame
    # (matmul, not einsum: several times faster on thousands of 3x3 blocks)
    cam = np.hstack([(dt[:, None, :] @ AX[:, :3, :3])[:, 0],
                     (B[:, :3, :3] @ dr[:, :, None])[..., 0]])
    return dt, dr, cam


def _weighted(x, A, B, X0, Y0, z_mm, W, target=False) -> np.ndarray:
    _, dr, cam = _raw_residuals(x, A, B, X0, Y0, z_mm)
    if target:      # the rotation in the target's frame
        cam = np.hstack([cam[:, :3], dr])
    return (cam @ W.T).ravel()


class _Stopped(Exception):
    """The least squares of the pairs stopped on its limit (the one solver's reason)."""


def _solve(A, B, X0, Y0, z_mm, W, x0, target=False) -> tuple[np.ndarray, np.ndarray]:
    """The parameters (11,) and the whitened Jacobian (6N, 11) at them: the one solver
    (:func:`vision_cal.model.solve.solve`, Levenberg-Marquardt, scipy's default
    tolerances); a solve stopped on its limit raises :class:`_Stopped`."""
    sol = solve(lambda x: _weighted(x, A, B, X0, Y0, z_mm, W, target), x0, method="lm",
                xtol=1e-8, ftol=1e-8, gtol=1e-8)
    if not sol:
        raise _Stopped(sol.reason)
    return sol.x, np.asarray(sol.jacobian)


def _hat(J: np.ndarray) -> np.ndarray:
    """The hat matrix's diagonal blocks (N, 6, 6) of the whitened Jacobian (6N, 11)."""
    U, s, _ = np.linalg.svd(J, full_matrices=False)
    Uk = U[:, s > 1e-9 * s[0]]
    Ub = Uk.reshape(J.shape[0] // 6, 6, -1)
    return np.einsum("nik,njk->nij", Ub, Ub)


def _floored(S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The eigenvalues (6,), floored at :data:`_TINY` squared, and eigenvectors (6, 6) of a
    6x6 covariance ``S`` (symmetrised, :data:`_TINY` squared added)."""
    vals, vecs = np.linalg.eigh(0.5 * (S + S.T) + _TINY**2 * np.eye(6))
    return np.maximum(vals, _TINY**2), vecs


def _whitener(S: np.ndarray) -> np.ndarray:
    """W with W S W^T = I (S: the residuals' 6x6 covariance, floored)."""
    vals, vecs = _floored(S)
    return (vecs / np.sqrt(vals)).T


def _noise(cam: np.ndarray, trim_alpha: float, W=None, hat=None) -> np.ndarray:
    """The 6x6 covariance of the pairs' camera-frame residual ``cam`` (N, 6), robust: the
    pairs whose Mahalanobis distance is beyond the chi-square's ``1 - trim_alpha`` point
    left out of it (and the variance such a cut removes from a normal's given back). Without
    a fit (``W`` None) each axis's scale comes from the median pair first; with the fit's
    whitener ``W`` and hat blocks ``hat`` (N, 6, 6), what the fit took from each direction
    is given back: the whitened residuals' scatter is ``sum (I - H_ii)`` where the noise is
    ``W^-1 W^-T``, so ``S = W^-1 M^-1/2 C M^-1/2 W^-T`` (C their scatter, M that sum)."""
    cut = float(stats.chi2.isf(trim_alpha, 6)) if trim_alpha > 0 else np.inf
    consistency = float(stats.chi2.cdf(cut, 8) / stats.chi2.cdf(cut, 6)) if np.isfinite(cut) else 1.0
    if W is None:
        med = np.median(cam**2, axis=0).clip(_TINY**2) / _CHI2_1_MEDIAN
        S = np.diag(med)
        for _ in range(4):
            d2 = np.sum((cam @ _whitener(S).T) ** 2, axis=1)
            keep = d2 <= max(cut, float(np.sort(d2)[min(6, len(d2) - 1)]))
            c = cam[keep]
            S = c.T @ c / max(len(c) - 11.0 / 6.0, 1.0) / consistency
        return S
    w = cam @ W.T
    keep = np.sum(w**2, axis=1) <= max(cut, float(np.sort(np.sum(w**2, axis=1))[min(6, len(w) - 1)]))
    C = w[keep].T @ w[keep] / consistency
    M = np.sum(np.eye(6) - hat[keep], axis=0)
    vals, vecs = np.linalg.eigh(0.5 * (M + M.T))
    Mih = (vecs / np.sqrt(np.maximum(vals, 1e-9))) @ vecs.T
    Wi = np.linalg.inv(W)
    return Wi @ Mih @ C @ Mih @ Wi.T


def _outlier_level(alpha: float, n_in: int) -> float:
    """The level a pair's deleted translation (or rotation) residual, 3-D and whitened axis
    by axis by variances the pairs estimate with ``nu`` dof each, passes by chance with
    probability ``alpha`` (each of the two: ``alpha / 2``): ``3 F(3, nu)``, the
    chi-square's level widened for variances known from few pairs."""
    nu = max(n_in - 1 - 11.0 / 6.0, 2.0)
    return float(3.0 * stats.f.isf(alpha / 2, 3, nu))


@dataclass(frozen=True)
class _Weighted:
    """A fit of pairs weighted by their own scatter: ``x`` (11,) the parameters (about the
    closed form), ``S`` (6, 6) the pairs' noise covariance in the camera frame, ``W`` its
    whitener, ``cov`` (11, 11) the parameters' covariance by the one policy (before the
    inverse Wishart's correction; a direction the pairs do not see: inf), ``hat`` (n, 6, 6) the hat matrix's diagonal blocks, of the pairs fitted,
    and ``J`` (6n, 11) the whitened Jacobian."""

    x: np.ndarray
    S: np.ndarray
    W: np.ndarray
    cov: np.ndarray
    hat: np.ndarray
    J: np.ndarray


@dataclass(frozen=True)
class _Robust:
    """The weighted fit of the inliers (``fit``), which pairs they are (``inlier`` (N,)
    bool) and why each other one was left out, or why no more were (``reasons``)."""

    fit: _Weighted
    inlier: np.ndarray
    reasons: tuple[str, ...]


def _refused(pairs: list[PosePair], mount: str, cfg: HandeyeConfig,
             z_mm: float | None) -> PairsFailed | None:
    """Why ``pairs`` cannot make a hand-eye before any fit (an unknown mount, too few or
    too many pairs, a height no target has, a flange that hardly turns); None: they can."""
    if mount not in MOUNTS:
        return PairsFailed(f"mount {mount!r}: expected one of {', '.join(MOUNTS)}")
    n = len(pairs)
    if n < cfg.min_pairs:
        return PairsFailed(f"{n} pairs: at least {cfg.min_pairs} are needed")
    if n > cfg.max_pairs:
        return PairsFailed(f"{n} pairs: at most {cfg.max_pairs} are read (the fit's cost "
                           "grows with them and a few hundred distinct poses fix the camera "
                           "as well as it can be): keep a subset")
    if z_mm is not None and not abs(z_mm) <= cfg.max_robot_mm:
        return PairsFailed(f"the target's height {z_mm:g} mm: a target within "
                           f"{cfg.max_robot_mm:g} mm of the {'robot' if mount == 'arm' else 'flange'}"
                           " frame's origin is expected (--z-mm and target_z_mm are in mm)")
    spread = yaw_spread_deg(np.array([p.T_robot_flange for p in pairs], float))
    if spread < cfg.min_yaw_spread_deg:
        yaws = [p.flange_yaw for p in pairs if p.flange_yaw is not None]
        rad = (" (every yaw written within +-3.15: in radians? yaw_deg is in degrees)"
               if yaws and max(abs(y) for y in yaws) <= 3.15 else "")
        return PairsFailed(f"the flange turns by at most {spread:.2f} deg between pairs{rad}: "
                           "a camera's place on the flange needs turns of joint 4 (or of "
                           f"the arm) of at least {cfg.min_yaw_spread_deg:g} deg")
    return None


def _weighted_fit(A, B, X0, Y0, z: float, x, trim_alpha: float) -> _Weighted:
    """The fit of pairs ``A``, ``B`` from ``x``, weighted by their noise: robust from the
    median pair first (``trim_alpha``: the chi-square's tail left out), then three rounds
    with the fit's leverage given back, and a last solve with the noise found."""
    x, J = _solve(A, B, X0, Y0, z, np.eye(6), x)
    S = _noise(_raw_residuals(x, A, B, X0, Y0, z)[2], trim_alpha)
    for _ in range(3):
        W = _whitener(S)
        x, J = _solve(A, B, X0, Y0, z, W, x)
        S = _noise(_raw_residuals(x, A, B, X0, Y0, z)[2], 0.0, W, _hat(J))
    W = _whitener(S)
    x, J = _solve(A, B, X0, Y0, z, W, x)
    # the residuals whitened by the pairs' own scatter: s^2 = 1
    cov = covariance(J, labels=LABELS, s2=1.0).stated
    return _Weighted(x, S, W, cov, _hat(J), J)


def _deleted(hat: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Deleted residuals ``(I - H_ii)^-1 w_i`` (k, 6) of whitened residuals ``w`` (k, 6)
    and their covariances ``(I - H_ii)^-1`` (k, 6, 6), from the hat blocks (k, 6, 6)."""
    Sd = np.linalg.inv(np.eye(6) - hat + 1e-12 * np.eye(6))
    return np.einsum("kij,kj->ki", Sd, w), Sd


def _deleted_t2(A, B, X0, Y0, z: float, x, inl: np.ndarray, alpha: float) -> np.ndarray:
    """Each inlier pair's deleted residual's T^2 at ``x`` (N,; 0 for the others), against
    the scatter of the inliers within the chi-square's ``1 - alpha`` level (a pair far off
    would widen its own yardstick), leverage included; the translation and the rotation
    tested apart (a pair off in one of them is not diluted by the other's three axes), the
    larger kept."""
    n = len(A)
    _, dr_all, cam_all = _raw_residuals(x, A, B, X0, Y0, z)
    # (a detector's rotation error is the same in every pair in the target's frame)
    seen = np.hstack([cam_all[:, :3], dr_all])
    S_in = _noise(seen[inl], alpha)
    W_in = _whitener(S_in)
    for _ in range(2):   # what the fit takes from each direction given back
        hat_in = _hat(_solve(A[inl], B[inl], X0, Y0, z, W_in, x, target=True)[1])
        S_in = _noise(seen[inl], alpha, W_in, hat_in)
        W_in = _whitener(S_in)
    # per axis only (6 variances, not 21 terms, from so few pairs: a far lower level); the
    # variances of the floored scatter the whitener holds
    vals, vecs = _floored(S_in)
    W_in = np.diag(1.0 / np.sqrt(np.einsum("ij,j,ij->i", vecs, vals, vecs)))
    hat_in = _hat(_solve(A[inl], B[inl], X0, Y0, z, W_in, x, target=True)[1])
    d, Sd = _deleted(hat_in, (seen @ W_in.T)[inl])      # each at half the level
    chi = np.zeros(n)
    chi[inl] = np.maximum(
        np.einsum("ki,ki->k", d[:, :3], np.linalg.solve(Sd[:, :3, :3], d[:, :3, None])[..., 0]),
        np.einsum("ki,ki->k", d[:, 3:], np.linalg.solve(Sd[:, 3:, 3:], d[:, 3:, None])[..., 0]))
    return chi


def _fit_with_outliers(pairs: list[PosePair], A, B, X0, Y0, z: float,
                       cfg: HandeyeConfig, inl: np.ndarray, reasons: list[str]) -> _Robust:
    """The weighted fit of the pairs ``inl`` (those the consensus kept), leaving out the
    pairs beyond the Bonferroni level :func:`_outlier_level` (deleted T^2), worst first,
    and fitting again, until none is over it or ``cfg.max_outlier_fraction`` of them are
    out. Every pair beyond the level goes in one round (the consensus has taken the gross
    ones, which could hide or drag others): rounds stay few whatever the pairs' number."""
    n = len(pairs)
    inl = inl.copy()
    reasons = list(reasons)
    max_out = int(math.floor(cfg.max_outlier_fraction * n))
    x = np.zeros(11)
    while True:
        limit = _outlier_level(cfg.outlier_alpha / n, int(inl.sum()))
        fit = _weighted_fit(A[inl], B[inl], X0, Y0, z, x, cfg.outlier_alpha)
        x = fit.x
        chi = _deleted_t2(A, B, X0, Y0, z, x, inl, cfg.outlier_alpha / n)
        idx = np.flatnonzero(inl)
        beyond = idx[chi[idx] > limit]
        if not len(beyond):
            break
        room = min(max_out - int((~inl).sum()), int(inl.sum()) - cfg.min_pairs)
        if room <= 0:
            reasons.append(f"more pairs disagree than {cfg.max_outlier_fraction:.0%} of them: "
                           "none more left out (a wrong mount, units or frame convention?)")
            break
        out = beyond[np.argsort(-chi[beyond])][:room]
        inl[out] = False
        dt_w, dr_w, _ = _raw_residuals(x, A[out], B[out], X0, Y0, z)
        reasons += [f"pair {pairs[i].id}: {float(np.linalg.norm(a)):.3f} mm, "
                    f"{float(np.linalg.norm(b)):.3f} deg from where the others put the "
                    f"target (T^2 {chi[i]:.0f}, the level {limit:.0f} for {len(idx)} pairs)"
                    for i, a, b in zip(out, dt_w, dr_w)]
    return _Robust(fit, inl, tuple(reasons))


def _per_pair(A, B, X0, Y0, z: float, r: _Robust) -> tuple[np.ndarray, np.ndarray, float]:
    """Per pair, in ``Y``'s parent frame: the leave-one-pair-out (deleted) translation
    residual (N, 3; outliers: their residual), the per-axis std of x, y from the pooled
    noise (N,); and the parameters the inliers' x, y rows consume (the hat matrix's trace
    over them)."""
    f, inl = r.fit, r.inlier
    X, _ = _unpack(f.x, X0, Y0, z)
    dt_all, _, cam_all = _raw_residuals(f.x, A, B, X0, Y0, z)
    Winv = np.linalg.inv(f.W)
    Rc = (A @ X)[:, :3, :3]
    St = np.einsum("nij,jk,nlk->nil", Rc, f.S[:3, :3], Rc)
    sig_xy = np.sqrt(np.maximum((St[:, 0, 0] + St[:, 1, 1]) / 2.0, 0.0))
    held = dt_all.copy()
    d, _ = _deleted(f.hat, (cam_all @ f.W.T)[inl])
    held[inl] = np.einsum("kij,kj->ki", Rc[inl], d @ Winv[:3, :].T)
    T = np.einsum("kij,jl,klm,mp,kqp->kiq", Rc[inl], Winv[:3, :], f.hat, f.W[:, :3], Rc[inl])
    p_xy = float(np.sum(T[:, 0, 0] + T[:, 1, 1]))
    return held, sig_xy, p_xy


def _not_identifiable(cov: np.ndarray, z_given: bool, cfg: HandeyeConfig,
                      unseen: list[tuple[list[str], str]]) -> tuple[dict, ...]:
    """The parameters the pairs do not determine (label, std, reason): the camera's height
    when the target's is not given, those a direction no pair sees moves (``unseen``:
    (labels, sentence) each; no std), and any whose std is over ``cfg``'s limits."""
    ni = [] if z_given else [{
        "label": "X_z_mm", "std": None,
        "reason": "a SCARA turns about its vertical axis only: the pairs see the difference "
                  "of the camera's and the target's heights, not either one; taken with the "
                  "target's origin at z = 0 (give the target's height: --z-mm)"}]
    named = {d["label"] for d in ni}
    for labels, sentence in unseen:
        for lab in labels:
            if lab not in named:
                named.add(lab)
                ni.append({"label": lab, "std": None, "reason": sentence})
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    for k, lab in enumerate(LABELS):
        if lab in named:
            continue
        lim = cfg.unidentified_std_deg if lab.endswith("_deg") else cfg.unidentified_std_mm
        if sd[k] > lim:
            ni.append({"label": lab, "std": float(sd[k]),
                       "reason": "the pairs do not determine it (turn the flange more, over "
                                 "more places)"})
    return tuple(ni)


def _consensus_out(pairs, A, B, X0, Y0, z: float, x, keep: np.ndarray, cfg: HandeyeConfig
                   ) -> list[str]:
    """Why each pair the consensus left out was (its distance from the fit ``x``)."""
    idx = np.flatnonzero(~keep)
    if not len(idx):
        return []
    dt, dr, _ = _raw_residuals(x, A[idx], B[idx], X0, Y0, z)
    return [f"pair {pairs[i].id}: {float(np.linalg.norm(a)):.3f} mm, "
            f"{float(np.linalg.norm(b)):.3f} deg from where the others put the target "
            f"(beyond {cfg.consensus_cut:g} times the agreement of the {int(keep.sum())} "
            "pairs that agree)" for i, a, b in zip(idx, dt, dr)]


def _findings(pairs, T, A, B, X, Y, z: float, mount: str, z_given: bool, r: _Robust,
              cfg: HandeyeConfig) -> tuple[list, list, object]:
    """The checks of :mod:`vision_cal.camera.pairs_checks` on the fitted pairs: findings
    ((status, sentence)), the unseen directions ((labels, sentence)) and the closed form's
    scale (on the inliers). A reading or a unit that explains the pairs far better comes
    first and alone: what else the fit says follows from it (a flange in metres "stands
    still", a wrong mount leaves half the pairs "outliers")."""
    inl = r.inlier
    yaws = [p.flange_yaw for p in pairs]
    rvecs = [p.target_rvec for p in pairs]
    cf = closed_form_parts(A[inl], B[inl], z)
    length = float(np.median(np.linalg.norm(B[:, :3, 3], axis=1)))
    unseen = [checks.null_sentence(v, LABELS, T[inl], length)
              for v in checks.null_directions(r.fit.J, LABELS, length)]
    conv = checks.convention_finding(
        T, B, mount, z, ratio=cfg.convention_ratio, sample=cfg.convention_sample,
        rvec=None if any(v is None for v in rvecs) else np.array(rvecs, float),
        yaw=None if any(v is None for v in yaws) else np.array(yaws, float))
    if conv:
        return [conv], unseen, cf
    units = checks.scale_finding(cf, unit_ratio=cfg.unit_ratio, min_rel=cfg.scale_min_rel,
                                 n_std=cfg.scale_sigma)
    if units and units[0] == "not reliable":
        return [units], unseen, cf
    found = [units] if units and not unseen else []
    reach = checks.reach_finding(T, min_reach_mm=cfg.min_reach_mm)
    if reach:
        found.append(reach)
    found += checks.size_findings(X, Y, B, mount, max_mount_mm=cfg.max_mount_mm,
                                  max_robot_mm=cfg.max_robot_mm, z_given=z_given)
    if (~inl).sum() > cfg.max_outlier_fraction * len(A):
        found.append(("not reliable", f"{int((~inl).sum())} of {len(A)} pairs disagree with the "
                                      f"others (more than {cfg.max_outlier_fraction:.0%}): the "
                                      "target's detection or the flange poses are suspect"))
    return found, unseen, cf


def _repeat_rows(pairs, d: checks.Distinct, x, A_all, B_all, X0, Y0, z: float):
    """The pairs at an earlier pair's flange pose: (id, first id) each, and their own
    residuals (R, 3) mm and deg at the fit ``x``."""
    rep = np.setdiff1d(np.arange(len(pairs)), d.first)
    if not len(rep):
        return (), None, None
    dt, dr, _ = _raw_residuals(x, A_all[rep], B_all[rep], X0, Y0, z)
    return (tuple((pairs[i].id, pairs[d.first[d.group[i]]].id) for i in rep), dt, dr)


def fit_pose_pairs(pairs: list[PosePair], mount: str = "arm", *, z_mm: float | None = None,
                   config: HandeyeConfig | None = None, progress: bool = False
                   ) -> PairsFit | PairsFailed:
    """The hand-eye of ``pairs`` (module docstring).

        fit = fit_pose_pairs(read_poses("pairs.json").pairs, "arm", z_mm=0.0)
        if not fit: print(fit.reason)                          # a PairsFailed

    ``z_mm`` the target origin's height in
    ``Y``'s parent frame (None: not known, 0 taken and the camera's height flagged);
    ``progress``: one line a stage on long work (thousands of pairs)."""
    cfg = config or DEFAULT.handeye
    failed = _refused(pairs, mount, cfg, z_mm)
    if failed is not None:
        return failed
    T_all = np.array([p.T_robot_flange for p in pairs], float)
    B_all = np.array([p.T_camera_target for p in pairs], float)
    d = checks.distinct_poses(T_all, B_all, cfg.repeat_mm, cfg.repeat_deg)
    if len(d.first) < cfg.min_pairs:
        return PairsFailed(f"{len(pairs)} pairs hold {len(d.first)} distinct flange poses: at "
                           f"least {cfg.min_pairs} are needed (a pose repeated counts once)")
    stages = bar(progress and len(pairs) >= cfg.progress_pairs, total=4, unit="stage",
                 desc="hand-eye from pose pairs", note=f"{len(pairs)} pairs")
    distinct = [pairs[i] for i in d.first]
    T, B = d.A, d.B
    A = _moving(T, mount)
    z = 0.0 if z_mm is None else float(z_mm)
    cons = checks.consensus(A, B, z, trials=cfg.consensus_trials, share=cfg.consensus_share,
                            cut=cfg.consensus_cut, min_yaw_deg=cfg.min_yaw_spread_deg)
    stages.update()
    # the start from the pairs that agree (the fit's rotations are small turns about it)
    X0, Y0 = closed_form(A[cons.inlier], B[cons.inlier], z)
    stages.update()
    try:
        r = _fit_with_outliers(distinct, A, B, X0, Y0, z, cfg, cons.inlier, [])
    except _Stopped as e:
        stages.close()
        return PairsFailed(f"the least squares of the pairs did not converge: {e}")
    if not cons.inlier.all():
        why = _consensus_out(distinct, A, B, X0, Y0, z, r.fit.x, cons.inlier, cfg)
        r = _Robust(r.fit, r.inlier, tuple(why) + r.reasons)
    stages.update()
    x, inl = r.fit.x, r.inlier
    X, Y = _unpack(x, X0, Y0, z)
    dt_all, dr_all, _ = _raw_residuals(x, A, B, X0, Y0, z)
    # the weights are the inverse of a covariance estimated from the pairs themselves,
    # which is too large on average by nu / (nu - 7) (the inverse Wishart's mean, 6 axes):
    # the parameters' covariance is scaled back by it
    nu = inl.sum() - 11.0 / 6.0
    cov = r.fit.cov * (nu / (nu - 7.0) if nu > 9.0 else 3.0)
    held, sig_xy, p_xy = _per_pair(A, B, X0, Y0, z, r)
    found, unseen, cf = _findings(distinct, T, A, B, X, Y, z, mount, z_mm is not None, r, cfg)
    reps, rep_mm, rep_deg = _repeat_rows(pairs, d, x, _moving(T_all, mount), B_all, X0, Y0, z)
    stages.update()
    stages.close()
    return PairsFit(mount, tuple(p.id for p in distinct), X, Y, cov, dt_all, dr_all, held, inl,
                    r.fit.S, sig_xy, p_xy, z, z_mm is not None, X0, Y0, r.reasons,
                    _not_identifiable(cov, z_mm is not None, cfg, unseen), tuple(found),
                    reps, rep_mm, rep_deg, tuple(lab for labs, _ in unseen for lab in labs),
                    cf.scale, cf.scale_std)
