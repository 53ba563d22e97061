"""What the hand-eye's residual says about its own noise, its stds and its predictions.

A photo's corners are off for three reasons: the detector (``sigma_d`` px per axis, every
corner on its own); the robot, whose flange was not exactly where the controller said (a
small rigid error ``D_i`` per photo, moving all of that photo's corners together: rotation
``sigma_rot`` deg and translation ``sigma_mm`` mm per axis); and the robot's kinematic
error, the part of ``D_i`` that is a smooth function of the arm's configuration (its model's
lengths and angles off: the same error for two photos taken in nearby configurations, a
different one in a far configuration; ``sigma_kin`` mm per axis, rotation ``sigma_kin /
lever`` rad, :func:`kinematic_kernel`). The least squares weighs every corner alike (the
plain joint least squares: on the real session it predicts held-out photos better than
letting each photo's pose float under a prior, docs/measured.md), so its covariance is the
sandwich ``H^-1 J^T Sigma J H^-1`` with ``Sigma = sigma_d^2 I + J_D (I (x) S + sigma_kin^2 K
(x) W) J_D^T``: block-diagonal by photo for the first two, full for the kinematic error,
whose part shared by all the photos the unknowns absorb (it moves ``X`` and ``Y`` and shows
in no residual: only its variation between the photos does, and the kernel ``K`` says how
much of it is shared); the one policy's sandwich
(:func:`vision_cal.model.solve.covariance`).

The four variances are estimated from the residual itself (:func:`noise_components`,
MINQUE: the quadratic forms ``r^T V_c r`` of the residual matched to their expectations
``sum_c' s_c' tr(V_c M V_c' M)``, ``M = I - J H^-1 J^T`` the residual maker, so the
parameters' share of the noise is not counted as noise). A component the photos cannot
tell apart from another (the flange's rotation and translation move a camera on the arm's
view alike) is estimated jointly: only what the pixels see matters to the stds.

Each photo's prediction from the others (leave one out, :func:`leave_one_out`) is judged
against what the fit of the others states for it: ``J_theta Cov J_theta^T + J_D (S +
sigma_kin^2 W) J_D^T + sigma_d^2 I`` with that fit's own covariance and noise (deleted
statistics: a photo far off cannot raise the noise it is judged by); a new pose is stated
the same (the kinematic error at it in full: no credit for photos taken nearby).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from vision_cal.camera.handeye_closed import inv_T
from vision_cal.camera.handeye_lsq import Problem, Refined, refine
from vision_cal.config import DEFAULT
from vision_cal.model.solve import covariance


@dataclass(frozen=True)
class Kinematic:
    """How the robot's kinematic error is shared between the photos: ``K`` (n, n) the
    correlation of two photos' flange errors, from their distance ``over`` the arm's
    ``joints`` (when the poses give them) or its ``flange poses`` (position over
    ``lever_mm`` and rotation, rad: the configuration is not known); ``lever_mm`` the
    flange's median distance from the robot's base, which turns a kinematic error's
    translation (mm) into its rotation (rad)."""

    K: np.ndarray
    lever_mm: float
    over: str

    @property
    def weights(self) -> np.ndarray:
        """(6,) the variance of D's rotation (deg^2) and translation (mm^2) per unit."""
        lever_deg = self.lever_mm * np.pi / 180.0
        return np.r_[[1.0 / lever_deg ** 2] * 3, [1.0] * 3]


def pose_distance(F: np.ndarray, lever_mm: float) -> np.ndarray:
    """(n, n) distances between flange poses ``F`` (n, 4, 4): the positions' over
    ``lever_mm`` and the rotation angle (rad), combined (rad)."""
    F = np.asarray(F, float)
    dp = np.linalg.norm(F[:, None, :3, 3] - F[None, :, :3, 3], axis=2) / lever_mm
    R = np.einsum("nji,mjk->nmik", F[:, :3, :3], F[:, :3, :3])    # R_a^T R_b
    tr = np.clip((np.einsum("nmii->nm", R) - 1.0) / 2.0, -1.0, 1.0)
    return np.hypot(dp, np.arccos(tr))


def joint_distance(q: np.ndarray) -> np.ndarray:
    """(n, n) distances (rad) between joint vectors ``q`` (n, J) deg, each joint's
    difference wrapped to +-180 deg."""
    d = (q[:, None, :] - q[None, :, :] + 180.0) % 360.0 - 180.0
    return np.linalg.norm(np.radians(d), axis=2)


@dataclass(frozen=True)
class Shared:
    """What the fit's unknowns took of the kinematic error, so that a new pose's prediction
    is credited with it: ``G`` (n, P, 6) with ``Cov(theta_hat - theta, D*) = sum_i k(i, *)
    G_i`` (``D*`` the flange's error at the new pose, ``k`` the kernel between photo ``i``
    and it); the photos' flange poses ``F`` (n, 4, 4) and joints (n, J) or None, and the
    kernel's ``length_rad`` and ``lever_mm``."""

    G: np.ndarray
    F: np.ndarray
    joints: np.ndarray | None
    length_rad: float
    lever_mm: float

    def k(self, F, joints=None) -> np.ndarray:
        """(n,) the kernel between a new pose (flange pose ``F``, its joints or None) and
        each photo: 0 when the photos' kernel was over joints and none are given (no
        credit: the configuration is not known)."""
        if self.joints is not None:
            if joints is None or len(joints) != self.joints.shape[1]:
                return np.zeros(len(self.F))
            d = joint_distance(np.vstack([np.asarray(joints, float)[None], self.joints]))
        else:
            d = pose_distance(np.concatenate([np.asarray(F, float)[None], self.F]),
                              self.lever_mm)
        return np.exp(-0.5 * (d[0, 1:] / self.length_rad) ** 2)

    def cross(self, F, joints=None) -> np.ndarray:
        """(P, 6) ``Cov(theta_hat - theta, D*)`` at a new pose."""
        return np.einsum("i,ipk->pk", self.k(F, joints), self.G)


def kinematic_kernel(views, length_rad: float) -> Kinematic:
    """The kinematic error's correlation between ``views`` (:class:`Kinematic`): a Gaussian
    of their distance over ``length_rad`` (``config.handeye_photos.kinematic_length_rad``:
    a length or angle of the model off turns with its joint, so two configurations one
    radian apart share its effect by about cos 1)."""
    length = float(length_rad)
    F = np.array([v.T_robot_flange for v in views], float)
    lever = float(np.median(np.linalg.norm(F[:, :3, 3], axis=1)))
    lever = max(lever, 1.0)
    q = [getattr(v, "joints_deg", None) for v in views]
    if all(x is not None for x in q) and len({len(x) for x in q}) == 1:
        d, over = joint_distance(np.array(q, float)), "joints"
    else:
        d, over = pose_distance(F, lever), "flange poses"
    return Kinematic(np.exp(-0.5 * (d / length) ** 2), lever, over)

@dataclass(frozen=True)
class Noise:
    """The residual's three variances: the detector's ``sigma_px`` (px per axis) and the
    robot's per-photo pose error ``sigma_rot_deg``, ``sigma_mm`` (per axis); ``pose_px``
    the RMS (per axis) the pose error gives a photo's corners, ``confounded`` when the
    photos could not tell the rotation from the translation (estimated together)."""

    sigma_px: float
    sigma_rot_deg: float
    sigma_mm: float
    pose_px: float
    confounded: bool
    kin_mm: float = 0.0        # the kinematic error (translation, mm per axis)
    lever_mm: float = 0.0      # ... its rotation is kin_mm / lever_mm rad
    kin_px: float = 0.0        # what it moves a photo's corners by (px per axis)
    kin_over: str = ""         # the distance its correlation is of: joints | flange poses

    @property
    def kin_deg(self) -> float:
        return float(np.degrees(self.kin_mm / self.lever_mm)) if self.lever_mm > 0 else 0.0

    def pose_variances(self) -> np.ndarray:
        """(6,) the variance of a new pose's flange error: rotation (deg^2) and translation
        (mm^2) per axis, the kinematic error's in full."""
        return np.r_[[self.sigma_rot_deg ** 2 + self.kin_deg ** 2] * 3,
                     [self.sigma_mm ** 2 + self.kin_mm ** 2] * 3]

    def to_json(self) -> dict:
        return {"corner_px": self.sigma_px, "robot_rotation_deg": self.sigma_rot_deg,
                "robot_translation_mm": self.sigma_mm, "robot_px": self.pose_px,
                "robot_rotation_and_translation_confounded": self.confounded,
                # added by issue 40's second part: the pose error shared by configurations
                "kinematic_translation_mm": self.kin_mm, "kinematic_rotation_deg": self.kin_deg,
                "kinematic_lever_mm": self.lever_mm, "kinematic_px": self.kin_px,
                "kinematic_over": self.kin_over}


def _blocks(view_of: np.ndarray) -> list[np.ndarray]:
    rows = np.repeat(view_of, 2)
    return [np.flatnonzero(rows == i) for i in range(int(view_of.max()) + 1)]


def _low_rank(Jd: np.ndarray, blocks, cols) -> np.ndarray:
    """U (2N, 3n) with U U^T = sum_i J_Di[:, cols] J_Di[:, cols]^T (block-diagonal)."""
    U = np.zeros((Jd.shape[0], len(cols) * len(blocks)))
    for i, b in enumerate(blocks):
        U[np.ix_(b, range(len(cols) * i, len(cols) * (i + 1)))] = Jd[np.ix_(b, cols)]
    return U


def _kinematic_low_rank(Jd: np.ndarray, blocks, kin: Kinematic) -> np.ndarray:
    """U (2N, 6n) with U U^T = J_D (K (x) W) J_D^T: the kinematic error's pixel covariance
    per unit variance (``K = B B^T``, each photo's six flange errors weighed by ``W``)."""
    w, V = np.linalg.eigh(kin.K)
    B = V * np.sqrt(np.clip(w, 0.0, None))
    JW = Jd * np.sqrt(kin.weights)
    U = np.zeros((Jd.shape[0], 6 * B.shape[1]))
    for i, b in enumerate(blocks):
        U[b] = np.einsum("rk,j->rjk", JW[b], B[i]).reshape(len(b), -1)
    return U


def _solve_components(G: np.ndarray, q: np.ndarray, keep: list[int]) -> np.ndarray:
    """The MINQUE equations ``G s = q`` over components ``keep``, a component estimated
    negative dropped and the others estimated again."""
    keep = list(keep)
    s = np.zeros(len(q))
    while keep:
        s = np.zeros(len(q))
        s[keep] = np.linalg.lstsq(G[np.ix_(keep, keep)], q[keep], rcond=None)[0]
        neg = [k for k in keep if s[k] < 0]
        if not neg:
            break
        keep.remove(min(neg, key=lambda k: s[k]))
    return np.clip(s, 0.0, None)


def noise_components(r: np.ndarray, Js: np.ndarray, Jd: np.ndarray, view_of: np.ndarray,
                     kin: Kinematic | None = None) -> Noise:
    """MINQUE of (sigma_d^2, sigma_rot^2, sigma_mm^2, sigma_kin^2) from the residual ``r``
    (N, 2) of a fit with Jacobian ``Js`` (2N, P) and the photos' pose Jacobians ``Jd``
    (2N, 6), the kinematic error shared as ``kin`` says (None: not estimated); a component
    estimated negative is dropped and the others estimated again."""
    r = np.asarray(r, float).ravel()
    blocks = _blocks(view_of)
    Hi = covariance(Js).matrix          # (J^T J)^-1 over what the photos fix: M below
    Us = [_low_rank(Jd, blocks, [0, 1, 2]), _low_rank(Jd, blocks, [3, 4, 5])]
    if kin is not None and len(blocks) > 1:
        Us.append(_kinematic_low_rank(Jd, blocks, kin))
    MU = [U - Js @ (Hi @ (Js.T @ U)) for U in Us]
    n2, P, m = len(r), Js.shape[1], len(Us) + 1
    # E[r^T V_c r] = sum_c' s_c' tr(V_c M V_c' M); V_d = I
    G = np.empty((m, m))
    G[0, 0] = n2 - P
    for a in range(m - 1):
        G[0, a + 1] = G[a + 1, 0] = float(np.sum(Us[a] * MU[a]))      # tr(V_a M)
        for b in range(m - 1):
            G[a + 1, b + 1] = float(np.sum((Us[a].T @ MU[b]) ** 2))
    q = np.r_[r @ r, [float(np.sum((U.T @ r) ** 2)) for U in Us]]
    confounded = np.linalg.cond(G[1:3, 1:3]) > 1e4
    if confounded:      # rotation and translation alike in the pixels: one pose term
        A = np.zeros((m - 1, m))        # the components estimated -> G's
        A[0, 0] = 1.0
        A[1, 1] = A[1, 2] = 1.0
        if m == 4:
            A[2, 3] = 1.0
        sc = _solve_components(A @ G @ A.T, A @ q, list(range(m - 1)))
        s = np.r_[sc[0], sc[1], sc[1:]]
    else:
        s = _solve_components(G, q, list(range(m)))
    s = np.r_[s, np.zeros(4 - len(s))]
    if s[0] <= 0:
        s[0] = max(float(r @ r) / max(n2 - P, 1), 1e-12)
    pose_var = s[1] * float(np.sum(Jd[:, :3] ** 2)) + s[2] * float(np.sum(Jd[:, 3:] ** 2))
    kin_var = 0.0 if kin is None else s[3] * float(np.sum(Jd ** 2 * kin.weights))
    return Noise(float(np.sqrt(s[0])), float(np.sqrt(s[1])), float(np.sqrt(s[2])),
                 float(np.sqrt(pose_var / n2)), bool(confounded),
                 float(np.sqrt(s[3])), 0.0 if kin is None else kin.lever_mm,
                 float(np.sqrt(kin_var / n2)), "" if kin is None else kin.over)


def photo_covariance(Jd_i: np.ndarray, noise: Noise) -> np.ndarray:
    """(2n_i, 2n_i) one photo's corner covariance: detector plus the robot's pose error
    (its kinematic error in full)."""
    return noise.sigma_px ** 2 * np.eye(len(Jd_i)) + (Jd_i * noise.pose_variances()) @ Jd_i.T


def sandwich(Js: np.ndarray, Jd: np.ndarray, view_of: np.ndarray, noise: Noise,
             kin: Kinematic | None = None) -> np.ndarray:
    """(P, P) covariance of the plain least squares' shared unknowns under ``noise`` (the
    kinematic error shared between the photos as ``kin`` says): the one policy's sandwich
    (:func:`vision_cal.model.solve.covariance`; a direction the photos do not fix has an
    infinite variance)."""
    P = Js.shape[1]
    meat = np.zeros((P, P))
    S = np.r_[[noise.sigma_rot_deg ** 2] * 3, [noise.sigma_mm ** 2] * 3]   # per photo; the
    blocks = _blocks(view_of)                                             # kinematic below
    for b in blocks:
        Jb = Js[b]
        C = noise.sigma_px ** 2 * np.eye(len(b)) + (Jd[b] * S) @ Jd[b].T
        meat += Jb.T @ C @ Jb
    if kin is not None and noise.kin_mm > 0 and len(blocks) > 1:
        A = Js.T @ _kinematic_low_rank(Jd, blocks, kin)
        meat += noise.kin_mm ** 2 * (A @ A.T)
    return covariance(Js, meat=meat).stated


@dataclass(frozen=True)
class HeldOut:
    """One photo predicted from the others: its error ``px`` (N_i, 2), in mm at the board
    ``mm`` (N_i, 2: the pixel error times the corner's depth over the focal length), the
    RMS of both, and what the fit states for it: ``stated_px`` (RMS per corner, 2-D) and
    the normalised error ``ratio`` = RMS / stated with its p-value (a chi-square with the
    Satterthwaite degrees of freedom of the stated covariance)."""

    name: str
    px: np.ndarray
    mm: np.ndarray
    rms_px: float
    rms_mm: float
    stated_px: float
    stated_mm: float
    ratio: float
    dof: float
    p_value: float
    sum_sq: float           # |e|^2 (px^2)
    expected_sq: float      # tr(stated covariance) (px^2)
    var_sq: float           # 2 tr(stated covariance^2): |e|^2's variance (px^4)


def depth_of(problem: Problem, p: np.ndarray) -> np.ndarray:
    """(N,) each corner's depth in the camera (mm)."""
    X, Y, _, _ = problem.unpack(p)
    G = problem.F if problem.mount == "fixed" else inv_T(problem.F)
    T = (inv_T(X)[None] @ G @ Y[None])[problem.view_of]
    return np.einsum("nj,nj->n", T[:, 2, :3], problem.pts) + T[:, 2, 3]


def predicted_covariance(Js: np.ndarray, Jd: np.ndarray, cov: np.ndarray, noise: Noise,
                         cross: np.ndarray | None = None, inflation: float = 1.0
                         ) -> np.ndarray:
    """(2m, 2m) the covariance of a new photo's prediction error (its Jacobians ``Js``,
    ``Jd``): the unknowns' ``cov``, the corners' noise and the flange's error there (raised
    by ``inflation``: ``cov`` and ``cross`` are given raised), less what the unknowns took
    of the kinematic error there (``cross``: ``Cov(theta_hat - theta, D*)``,
    :meth:`Shared.cross`)."""
    C = Js @ cov @ Js.T + inflation ** 2 * photo_covariance(Jd, noise)
    if cross is not None:
        A = Js @ cross @ Jd.T
        C -= A + A.T
    return C


def held_out(problem_k: Problem, p_k: np.ndarray, cov_k: np.ndarray, noise: Noise,
             name: str, cross: np.ndarray | None = None) -> HeldOut:
    """Photo ``problem_k`` (one view, the unknowns fixed at ``p_k`` fitted without it)
    predicted, against the stated covariance (``cov_k`` of the shared unknowns, ``cross``
    their covariance with the flange's error there: :func:`predicted_covariance`)."""
    e = problem_k.predict(p_k) - problem_k.px
    Js, Jd = problem_k.jacobians(p_k)
    C = predicted_covariance(Js, Jd, cov_k, noise, cross)
    f = 0.5 * (problem_k.lens0[0] + problem_k.lens0[1]) if not problem_k.free[0] else \
        0.5 * float(np.sum(p_k[12:14]))
    z = depth_of(problem_k, p_k)
    mm = e * (z / f)[:, None]
    n = len(e)
    tr, tr2 = float(np.trace(C)), float(np.sum(C * C))
    ss = float(np.sum(e ** 2))
    dof = tr ** 2 / tr2 if tr2 > 0 else float(2 * n)
    ratio = float(np.sqrt(ss / tr)) if tr > 0 else float("inf")
    p = float(stats.chi2.sf(ss / tr * dof, dof)) if tr > 0 else 0.0
    stated_mm = float(np.sqrt(tr / n)) * float(np.mean(z / f))
    return HeldOut(name, e, mm, float(np.sqrt(ss / n)), float(np.sqrt(np.sum(mm ** 2) / n)),
                   float(np.sqrt(tr / n)), stated_mm, ratio, dof, p, ss, tr, 2 * tr2)


def shared_part(Js: np.ndarray, Jd: np.ndarray, view_of: np.ndarray, noise: Noise, views,
                kin: Kinematic, length_rad: float) -> Shared:
    """The :class:`Shared` of a fit (its Jacobians, noise and photos)."""
    Hi = covariance(Js).matrix          # (J^T J)^-1 over what the photos fix (one policy)
    G = np.array([noise.kin_mm ** 2 * (Hi @ Js[b].T @ (Jd[b] * kin.weights))
                  for b in _blocks(view_of)])
    q = [getattr(v, "joints_deg", None) for v in views]
    return Shared(G, np.array([v.T_robot_flange for v in views], float),
                  np.array(q, float) if kin.over == "joints" else None, float(length_rad),
                  kin.lever_mm)


def statistics(views, mount: str, fit: Refined, *, kinematic: float | None = None
               ) -> tuple[np.ndarray, Noise, Shared | None]:
    """The covariance of ``fit`` (of ``views``), its noise and what its unknowns took of
    the kinematic error (:class:`Shared`; None without a kinematic term), the kernel of
    correlation length ``kinematic`` (rad; None: the configuration's; 0: the robot's pose
    error taken as independent from photo to photo, as before issue 40's second part)."""
    pr = Problem(views, mount, fit.X, fit.Y, fit.lens, fit.free)
    Js, Jd = pr.jacobians(pr.start())
    length = DEFAULT.handeye_photos.kinematic_length_rad if kinematic is None else kinematic
    kin = kinematic_kernel(views, length) if length > 0 else None
    noise = noise_components(fit.residual_px, Js, Jd, fit.view_of, kin)
    shared = (shared_part(Js, Jd, fit.view_of, noise, views, kin, length)
              if kin is not None and len(views) > 1 else None)
    return sandwich(Js, Jd, fit.view_of, noise, kin), noise, shared


def deleted_statistics(views, mount: str, fit: Refined, *, kinematic: float | None = None
                       ) -> tuple[Refined, np.ndarray, Noise, Shared | None]:
    """The fit of ``views`` started at ``fit``, its covariance, its noise and its share of
    the kinematic error (the photos' own: used to judge a photo left out of them)."""
    r = refine(Problem(views, mount, fit.X, fit.Y, fit.lens, fit.free))
    cov, noise, shared = statistics(views, mount, r, kinematic=kinematic)
    return r, cov, noise, shared


def leave_one_out(views, mount: str, fit: Refined, *, kinematic: float | None = None
                  ) -> list[HeldOut]:
    """Each photo predicted from a fit of the others (started at ``fit``), judged against
    what that fit states: its own covariance of the unknowns and its own noise (a photo
    far off does not raise the noise it is judged by: deleted statistics)."""
    out = []
    for k in range(len(views)):
        rk, cov_k, noise_k, sh = deleted_statistics(views[:k] + views[k + 1:], mount, fit,
                                                    kinematic=kinematic)
        one = Problem([views[k]], mount, rk.X, rk.Y, rk.lens, fit.free)
        cross = (None if sh is None else
                 sh.cross(views[k].T_robot_flange, getattr(views[k], "joints_deg", None)))
        out.append(held_out(one, one.start(), cov_k, noise_k, views[k].name, cross))
    return out
