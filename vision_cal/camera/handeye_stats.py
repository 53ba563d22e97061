"""What the hand-eye's residual says about its own noise, its stds and its predictions.

A photo's corners are off for two reasons: the detector (``sigma_d`` px per axis, every
corner on its own) and the robot, whose flange was not exactly where the controller said
(a small rigid error ``D_i`` per photo, moving all of that photo's corners together:
rotation ``sigma_rot`` deg and translation ``sigma_mm`` mm per axis). The least squares
weighs every corner alike (the plain joint least squares: on the real session it predicts
held-out photos better than letting each photo's pose float under a prior, docs/measured.md),
so its covariance is the sandwich ``H^-1 J^T Sigma J H^-1`` (the one policy,
:func:`vision_cal.model.solve.covariance`) with ``Sigma`` block-diagonal by photo:
``sigma_d^2 I + J_Di diag(sigma_rot^2, sigma_mm^2) J_Di^T``.

The three variances are estimated from the residual itself (:func:`noise_components`,
MINQUE: the quadratic forms ``r^T V_c r`` of the residual matched to their expectations
``sum_c' s_c' tr(V_c M V_c' M)``, ``M = I - J H^-1 J^T`` the residual maker, so the
parameters' share of the noise is not counted as noise). A component the photos cannot
tell apart from another (the flange's rotation and translation move a camera on the arm's
view alike) is estimated jointly: only what the pixels see matters to the stds.

Each photo's prediction from the others (leave one out, :func:`leave_one_out`) is judged
against what the fit of the others states for it: ``J_theta Cov J_theta^T + J_D Sigma_D
J_D^T + sigma_d^2 I`` with that fit's own covariance and noise (deleted statistics: a photo
far off cannot raise the noise it is judged by).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from vision_cal.camera.handeye_closed import inv_T
from vision_cal.camera.handeye_lsq import Problem, Refined, refine
from vision_cal.model.solve import covariance

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

    def to_json(self) -> dict:
        return {"corner_px": self.sigma_px, "robot_rotation_deg": self.sigma_rot_deg,
                "robot_translation_mm": self.sigma_mm, "robot_px": self.pose_px,
                "robot_rotation_and_translation_confounded": self.confounded}


def _blocks(view_of: np.ndarray) -> list[np.ndarray]:
    rows = np.repeat(view_of, 2)
    return [np.flatnonzero(rows == i) for i in range(int(view_of.max()) + 1)]


def _low_rank(Jd: np.ndarray, blocks, cols) -> np.ndarray:
    """U (2N, 3n) with U U^T = sum_i J_Di[:, cols] J_Di[:, cols]^T (block-diagonal)."""
    U = np.zeros((Jd.shape[0], len(cols) * len(blocks)))
    for i, b in enumerate(blocks):
        U[np.ix_(b, range(len(cols) * i, len(cols) * (i + 1)))] = Jd[np.ix_(b, cols)]
    return U


def noise_components(r: np.ndarray, Js: np.ndarray, Jd: np.ndarray, view_of: np.ndarray
                     ) -> Noise:
    """MINQUE of (sigma_d^2, sigma_rot^2, sigma_mm^2) from the residual ``r`` (N, 2) of a
    fit with Jacobian ``Js`` (2N, P) and the photos' pose Jacobians ``Jd`` (2N, 6); a
    component estimated negative is dropped and the others estimated again."""
    r = np.asarray(r, float).ravel()
    blocks = _blocks(view_of)
    Hi = covariance(Js).matrix          # (J^T J)^-1 over what the photos fix: M below
    Us = [_low_rank(Jd, blocks, [0, 1, 2]), _low_rank(Jd, blocks, [3, 4, 5])]
    MU = [U - Js @ (Hi @ (Js.T @ U)) for U in Us]
    n2, P = len(r), Js.shape[1]
    # E[r^T V_c r] = sum_c' s_c' tr(V_c M V_c' M); V_d = I
    G = np.empty((3, 3))
    G[0, 0] = n2 - P
    for a in range(2):
        G[0, a + 1] = G[a + 1, 0] = float(np.sum(Us[a] * MU[a]))      # tr(V_a M)
        for b in range(2):
            G[a + 1, b + 1] = float(np.sum((Us[a].T @ MU[b]) ** 2))
    q = np.r_[r @ r, [float(np.sum((U.T @ r) ** 2)) for U in Us]]
    keep = [0, 1, 2]
    s = np.zeros(3)
    confounded = np.linalg.cond(G[1:, 1:]) > 1e4
    if confounded:      # rotation and translation alike in the pixels: one pose term
        Gc = np.array([[G[0, 0], G[0, 1] + G[0, 2]],
                       [G[1, 0] + G[2, 0], G[1:, 1:].sum()]])
        sc = np.linalg.solve(Gc, np.r_[q[0], q[1] + q[2]])
        s = np.r_[sc[0], sc[1], sc[1]]
    else:
        while keep:
            s = np.zeros(3)
            s[keep] = np.linalg.lstsq(G[np.ix_(keep, keep)], q[keep], rcond=None)[0]
            neg = [k for k in keep if s[k] < 0]
            if not neg:
                break
            keep.remove(min(neg, key=lambda k: s[k]))
    s = np.clip(s, 0.0, None)
    if s[0] <= 0:
        s[0] = max(float(r @ r) / max(n2 - P, 1), 1e-12)
    pose_var = s[1] * float(np.sum(Jd[:, :3] ** 2)) + s[2] * float(np.sum(Jd[:, 3:] ** 2))
    return Noise(float(np.sqrt(s[0])), float(np.sqrt(s[1])), float(np.sqrt(s[2])),
                 float(np.sqrt(pose_var / n2)), bool(confounded))


def photo_covariance(Jd_i: np.ndarray, noise: Noise) -> np.ndarray:
    """(2n_i, 2n_i) one photo's corner covariance: detector plus the robot's pose error."""
    S = np.diag([noise.sigma_rot_deg ** 2] * 3 + [noise.sigma_mm ** 2] * 3)
    return noise.sigma_px ** 2 * np.eye(len(Jd_i)) + Jd_i @ S @ Jd_i.T


def sandwich(Js: np.ndarray, Jd: np.ndarray, view_of: np.ndarray, noise: Noise) -> np.ndarray:
    """(P, P) covariance of the plain least squares' shared unknowns under ``noise``: the
    one policy's sandwich (:func:`vision_cal.model.solve.covariance`; a direction the photos
    do not fix has an infinite variance)."""
    P = Js.shape[1]
    meat = np.zeros((P, P))
    for b in _blocks(view_of):
        Jb = Js[b]
        meat += Jb.T @ photo_covariance(Jd[b], noise) @ Jb
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


def held_out(problem_k: Problem, p_k: np.ndarray, cov_k: np.ndarray, noise: Noise,
             name: str) -> HeldOut:
    """Photo ``problem_k`` (one view, the unknowns fixed at ``p_k`` fitted without it)
    predicted, against the stated covariance (``cov_k`` of the shared unknowns)."""
    e = problem_k.predict(p_k) - problem_k.px
    Js, Jd = problem_k.jacobians(p_k)
    C = Js @ cov_k @ Js.T + photo_covariance(Jd, noise)
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


def deleted_statistics(views, mount: str, fit: Refined) -> tuple[Refined, np.ndarray, Noise]:
    """The fit of ``views`` started at ``fit``, its covariance and its noise (the photos'
    own: used to judge a photo left out of them)."""
    r = refine(Problem(views, mount, fit.X, fit.Y, fit.lens, fit.free))
    pr = Problem(views, mount, r.X, r.Y, r.lens, fit.free)
    Js, Jd = pr.jacobians(pr.start())
    noise = noise_components(r.residual_px, Js, Jd, r.view_of)
    return r, sandwich(Js, Jd, r.view_of, noise), noise


def leave_one_out(views, mount: str, fit: Refined) -> list[HeldOut]:
    """Each photo predicted from a fit of the others (started at ``fit``), judged against
    what that fit states: its own covariance of the unknowns and its own noise (a photo
    far off does not raise the noise it is judged by: deleted statistics)."""
    out = []
    for k in range(len(views)):
        rk, cov_k, noise_k = deleted_statistics(views[:k] + views[k + 1:], mount, fit)
        one = Problem([views[k]], mount, rk.X, rk.Y, rk.lens, fit.free)
        out.append(held_out(one, one.start(), cov_k, noise_k, views[k].name))
    return out
