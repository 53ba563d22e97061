"""Hand-eye for any arm from photos of a board and the robot's flange poses
(``vision-cal handeye PHOTOS/ --robot-poses POSES --sheet BOARD --mount fixed|arm``).

The stages (:func:`fit_handeye`):

1. the lens: the one declared, else a start from the board's views alone (OpenCV's
   ``calibrateCamera``), estimated with the rest in stage 4 with each distortion model of
   ``config.lens_models``, the one whose held-out photos are predicted best kept;
2. each photo's board pose (PnP): a photo whose corners its own pose cannot fit
   (``photo_fit_factor`` times the median photo's residual) does not show this board and
   is left out, named;
3. the checks of the poses against what the camera saw, before anything is fitted: the
   flange must turn, about more than one axis (all turns about one axis, a SCARA's, leave
   the translation along it unseen: named, with the 4-DOF path to take); the robot's
   rotations between photos must be the board's (a quaternion read in another order, or
   inverted poses, or poses shifted by one photo, fit far better: the refusal names which);
   the robot's motion and the board's must agree in scale (units, the board's size);
4. the closed form (:func:`vision_cal.camera.handeye_closed.solve_axzb`), then ONE least
   squares of every corner of every photo (:mod:`vision_cal.camera.handeye_lsq`);
5. the statistics (:mod:`vision_cal.camera.handeye_stats`): the corners' and the robot's
   noise from the residual, the stds (sandwich), each photo predicted from the others
   against what is stated for it; a photo predicted beyond what it should be (at
   ``outlier_alpha / n``, and ``outlier_ratio`` times farther off than stated) is left out
   and the fit made again; held-out photos predicted worse than stated raise every std and
   stated error to what they show (the verdict says so when it is significant).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy import stats

from vision_cal.camera.handeye_closed import (AxzbSolution, axis_spread, inv_T,
                                              rotation_spread_deg, solve_axzb)
from vision_cal.camera.handeye_lsq import (LENS_NAMES, MOUNTS, Problem, Refined, View,
                                           lens_K, lens_vector, refine)
from vision_cal.camera.handeye_stats import HeldOut, Noise, Shared, leave_one_out, statistics
from vision_cal.camera.robot_poses import likely_unit
from vision_cal.config import DEFAULT, HandeyePhotosConfig
from vision_cal.errors import CalibrationError, VisionCalError

#: what X and Y are called, by mount (the contract's names)
NAMES = {"fixed": ("T_robot_camera", "T_flange_board"), "arm": ("T_flange_camera", "T_robot_board")}


@dataclass(frozen=True)
class HandeyeFit:
    """The hand-eye found: ``X``, ``Y`` (4, 4, mm; :data:`NAMES` by mount), the lens (9,:
    fx fy cx cy k1 k2 p1 p2 k3) and whether it was ``declared``; ``cov`` (P, P) of
    ``labels`` (raised by ``inflation`` where held-out photos demand it); the photos used
    (``views``) and left out (``left_out``: name -> reason); the residual of each photo
    (``residual_px`` RMS, 2-D) and each one's prediction from the others (``heldout``);
    the noise the residual shows; the closed-form start and the robot scale it found; each
    photo's own pose fit (``pnp_px``); an estimated lens's models tried (``lens_models``)."""

    mount: str
    X: np.ndarray
    Y: np.ndarray
    lens: np.ndarray
    free: np.ndarray
    declared: bool
    cov: np.ndarray
    labels: tuple[str, ...]
    views: tuple[View, ...]
    left_out: dict
    residual_px: dict
    heldout: tuple[HeldOut, ...]
    noise: Noise
    inflation: float
    heldout_ratio: float
    heldout_p: float
    start: AxzbSolution
    robot_scale: float
    pnp_px: dict
    size_px: tuple[int, int]
    lens_models: tuple = field(default=())   # (terms, held-out px) of each model tried
    shared: Shared | None = None      # what the unknowns took of the kinematic error
                                      # (its G raised by inflation^2, as cov)

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov), 0.0, None))

    @property
    def names(self) -> tuple[str, str]:
        return NAMES[self.mount]

    def heldout_rms(self) -> tuple[float, float, float, float]:
        """(observed px, stated px, observed mm, stated mm): RMS per corner (2-D) over every
        held-out photo; the stated figures include ``inflation``."""
        n = sum(len(h.px) for h in self.heldout)
        obs = float(np.sqrt(sum(h.sum_sq for h in self.heldout) / n))
        st = float(np.sqrt(sum(h.expected_sq for h in self.heldout) / n)) * self.inflation
        obs_mm = float(np.sqrt(sum(h.rms_mm ** 2 * len(h.px) for h in self.heldout) / n))
        st_mm = float(np.sqrt(sum(h.stated_mm ** 2 * len(h.px) for h in self.heldout) / n)
                      ) * self.inflation
        return obs, st, obs_mm, st_mm


# --------------------------------------------------------------------------- stage 1 and 2

def lens_start(views, size_px, terms) -> np.ndarray:
    """A lens from the board's views alone (OpenCV's ``calibrateCamera``, the distortion
    ``terms`` free, the others zero): the start of an undeclared lens."""
    # OpenCV takes 0.2 s to import: loaded here, when a lens must be found
    import cv2

    flags = cv2.CALIB_FIX_K3 if "k3" not in terms else 0
    if "k2" not in terms:
        flags |= cv2.CALIB_FIX_K2
    if "k1" not in terms:
        flags |= cv2.CALIB_FIX_K1
    if "p1" not in terms:
        flags |= cv2.CALIB_ZERO_TANGENT_DIST
    objs = [np.asarray(v.board_mm, np.float32) for v in views]
    imgs = [np.asarray(v.px, np.float32) for v in views]
    try:
        _, K, dist, _, _ = cv2.calibrateCamera(objs, imgs, tuple(int(s) for s in size_px),
                                               None, None, flags=flags)
    except cv2.error as e:
        raise CalibrationError(f"the lens cannot be estimated from these views ({e.msg}): "
                               "declare it (--camera)") from e
    return lens_vector(K, np.asarray(dist).ravel())


def board_poses(views, lens: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """Each photo's board in the camera (PnP with ``lens``) and its corners' RMS (px, 2-D)."""
    import cv2   # OpenCV takes 0.2 s to import: loaded here, when used

    K, dist = lens_K(lens), lens[4:]
    out, rms = [], []
    for v in views:
        ok, rv, tv = cv2.solvePnP(np.asarray(v.board_mm, float), np.asarray(v.px, float), K,
                                  dist, flags=cv2.SOLVEPNP_ITERATIVE)
        ok, rv, tv = cv2.solvePnP(np.asarray(v.board_mm, float), np.asarray(v.px, float), K,
                                  dist, rv, tv, useExtrinsicGuess=True,
                                  flags=cv2.SOLVEPNP_ITERATIVE)
        C = np.eye(4)
        C[:3, :3] = cv2.Rodrigues(rv)[0]
        C[:3, 3] = np.asarray(tv).ravel()
        uv = cv2.projectPoints(np.asarray(v.board_mm, float), rv, tv, K, dist)[0].reshape(-1, 2)
        out.append(C)
        rms.append(float(np.sqrt(np.mean(np.sum((uv - v.px) ** 2, axis=1)))))
    return out, np.array(rms)


def misfit_photos(pnp_rms: np.ndarray, cfg: HandeyePhotosConfig) -> list[int]:
    """Photos whose own pose cannot fit their corners (see the module docstring)."""
    med = float(np.median(pnp_rms))
    return [i for i, r in enumerate(pnp_rms)
            if r > cfg.photo_fit_factor * med and r > cfg.photo_fit_px]


# --------------------------------------------------------------------------- stage 3

def _G(F: np.ndarray, mount: str) -> np.ndarray:
    return F if mount == "fixed" else inv_T(F)


def check_motion(A, cfg: HandeyePhotosConfig) -> None:
    """The flange turned enough, about more than one axis (else ``CalibrationError``)."""
    spread = rotation_spread_deg(A)
    if spread < cfg.min_rotation_spread_deg:
        raise CalibrationError(
            f"the flange turned by at most {spread:.2g} deg between photos (at least "
            f"{cfg.min_rotation_spread_deg:g} needed): turn the flange between photos, about "
            "different axes")
    ax = axis_spread(A)
    if ax < cfg.min_axis_spread_deg:
        raise CalibrationError(
            f"every turn of the flange is about one axis (the turns off it: {ax:.2g} deg): "
            "the camera's place along that axis cannot be seen (a SCARA's poses: use "
            "`vision-cal handeye --poses PAIRS --z-mm H`, the 4-DOF hand-eye, with the "
            "height given; or tilt the flange between photos)")


def _rotation_rms(A, B) -> float:
    return solve_axzb(A, B).rotation_rms_deg


def check_conventions(views, C, mount: str, alternatives: dict,
                      cfg: HandeyePhotosConfig, source: str | None) -> None:
    """The robot's rotations between photos are the board's: else the reading that makes
    them so (``alternatives``: name -> (n, 4, 4) poses read another way), or the poses
    shifted by one photo, is named (``VisionCalError``)."""
    F = np.array([v.T_robot_flange for v in views])
    base = _rotation_rms([_G(f, mount) for f in F], C)
    tol = cfg.max_rotation_disagreement_deg
    if base <= tol:
        return
    tried = []
    for name, Fa in alternatives.items():
        tried.append((_rotation_rms([_G(f, mount) for f in Fa], C), name))
    other = "fixed" if mount == "arm" else "arm"
    tried.append((_rotation_rms([_G(f, other) for f in F], C),
                  f"the camera {'on the arm' if other == 'arm' else 'fixed'} "
                  f"(--mount {other})"))
    n = len(F)
    for s in (1, -1):
        if n - 1 >= 3:
            idx = np.arange(max(0, s), n + min(0, s))
            side = "before" if s > 0 else "after"
            tried.append((_rotation_rms([_G(F[i - s], mount) for i in idx],
                                        [C[i] for i in idx]),
                          f"each photo paired with the pose of the photo {side} it "
                          "(the poses shifted by one photo)"))
    best, name = min(tried)
    head = (f"the robot's rotations between photos disagree with the board's as the camera "
            f"saw them by {base:.3g} deg RMS (at most {tol:g} expected)")
    if best <= tol and best < base / 5:
        raise VisionCalError(f"{head}; read as {name} they agree within {best:.2g} deg",
                             file=source, field="--robot-poses")
    raise VisionCalError(f"{head}, and no other reading agrees (best: {name}, {best:.3g} deg): "
                         "are these the poses of these photos, T_robot_flange as x y z qx qy "
                         "qz qw?", file=source, field="--robot-poses")


def check_scale(A, C, cfg: HandeyePhotosConfig, source: str | None, units: str, *,
                declared: bool = True) -> float:
    """The robot's translations and the board's as seen agree in scale (else the likely
    unit, or the board's size, is named); the scale found. With an estimated lens (its
    start off by some %: ``declared`` False) only a unit's factor or more than
    ``max_scale_error_estimated`` is refused."""
    s = solve_axzb(A, C, free_scale=True).scale
    if not np.isfinite(s) or s <= 0:
        raise CalibrationError("the robot's motion and the board's as seen cannot be put in "
                               "one scale (the poses hardly turn)")
    tol = cfg.max_scale_error if declared else cfg.max_scale_error_estimated
    if abs(s - 1.0) <= tol and likely_unit(s, units) is None:
        return s
    unit = likely_unit(s, units)
    if unit is not None:
        raise VisionCalError(f"the robot moved {1 / s:.4g} times as far as the board the "
                             f"camera saw: the poses are in {unit}, read as "
                             f"{'metres' if units == 'm' else 'millimetres'}", file=source,
                             field="--robot-poses")
    raise CalibrationError(
        f"the robot's motion is {s:.4g} times the board's as the camera saw it (within "
        f"{100 * tol:g} % of 1 expected): is the board's size right (its "
        "square or marker size in sheet.json), the declared lens's focal length, and the "
        "poses' units?")


def _disagreement(A, C, cfg: HandeyePhotosConfig, scale_tol: float) -> float:
    """How far the photos' poses are from one hand-eye, in units of what is tolerated: the
    closed form's rotation RMS over ``max_rotation_disagreement_deg``, or the robot
    scale's distance from 1 over ``scale_tol`` (the larger)."""
    sol = solve_axzb(A, C, free_scale=True)
    if not np.isfinite(sol.scale):
        return float("inf")
    return max(sol.rotation_rms_deg / cfg.max_rotation_disagreement_deg,
               abs(sol.scale - 1.0) / scale_tol)


def consistent_photos(A, C, cfg: HandeyePhotosConfig, max_out: int, *,
                      declared: bool = True) -> list[int] | None:
    """The photos that agree with one hand-eye: all of them, or all but at most
    ``max_out`` each of which alone makes the others disagree (leaving it out at least
    halves the disagreement: a photo, not the whole set, is at fault); None when that does
    not make them agree (the poses, the lens or the board as a whole contradict the photos:
    the checks then name why)."""
    keep = list(range(len(A)))
    A, C = np.asarray(A), np.asarray(C)
    tol = cfg.max_scale_error if declared else cfg.max_scale_error_estimated

    def _dis(ks):
        return _disagreement(A[ks], C[ks], cfg, tol)

    bad = _dis(keep)
    while bad > 1.0:
        if len(keep) - 1 < max(3, len(A) - max_out):
            return None
        trial = min(([k for k in keep if k != i] for i in keep), key=_dis)
        after = _dis(trial)
        if after > bad / 2:
            return None
        keep, bad = trial, after
    return keep


# --------------------------------------------------------------------------- stages 4 and 5

@dataclass(frozen=True)
class _Judged:
    refined: Refined
    cov: np.ndarray
    noise: Noise
    heldout: list
    shared: Shared | None


def _judge(views, mount, X0, Y0, lens, free, kinematic: float) -> _Judged:
    """The least squares, its noise and stds, and each photo predicted from the others."""
    R = refine(Problem(views, mount, X0, Y0, lens, free))
    cov, noise, shared = statistics(views, mount, R, kinematic=kinematic)
    return _Judged(R, cov, noise, leave_one_out(views, mount, R, kinematic=kinematic), shared)


def _outlier_p(heldout, cfg: HandeyePhotosConfig) -> np.ndarray:
    """Each photo's p-value of its held-out error against what is stated for it, the
    statement first raised by the photos' median ratio when they are all predicted worse
    than stated (an outlier is a photo the others do not predict, not a noise the fit
    underrates for all of them); 1 for a photo less than ``outlier_ratio`` times farther
    off than stated."""
    r2 = np.array([h.sum_sq / h.expected_sq for h in heldout])
    k2 = max(1.0, float(np.median(r2)))
    return np.array([stats.chi2.sf(r / k2 * h.dof, h.dof) if r / k2 > cfg.outlier_ratio ** 2
                     else 1.0 for r, h in zip(r2, heldout)])


def _heldout_test(heldout) -> tuple[float, float]:
    """(ratio, p): held-out photos' error over what is stated (RMS), and the p-value of
    seeing that much or more (Satterthwaite chi-square of the summed squares)."""
    ss = sum(h.sum_sq for h in heldout)
    ex = sum(h.expected_sq for h in heldout)
    var = sum(h.var_sq for h in heldout)
    dof = 2 * ex * ex / var if var > 0 else 1.0
    return float(np.sqrt(ss / ex)), float(stats.chi2.sf(ss / ex * dof, dof))


@dataclass(frozen=True)
class _Prepared:
    """Stages 1-3 done: the photos kept, their board poses, the closed form and the scale,
    the photos left out so far (name -> reason), each photo's own pose fit."""

    views: list
    start: AxzbSolution
    scale: float
    left: dict
    pnp_px: dict


def _prepare(views, mount, size_px, lens0, declared, alternatives, source, units,
             cfg: HandeyePhotosConfig) -> _Prepared:
    """Stages 2 and 3 (the module docstring): the photos that fit the board and agree with
    one hand-eye, the checks' refusals, the closed form."""
    left: dict = {}
    C, pnp = board_poses(views, lens0)
    pnp_px = {v.name: float(r) for v, r in zip(views, pnp)}
    bad = misfit_photos(pnp, cfg)
    for i in bad:
        left[views[i].name] = (f"its corners do not fit the board ({pnp[i]:.3g} px RMS from "
                               f"its own best pose, {np.median(pnp):.2g} px for the median "
                               "photo): another board, a misdetection, or a lens far off there")
    keep = [i for i in range(len(views)) if i not in bad]
    views, C = [views[i] for i in keep], [C[i] for i in keep]
    alternatives = {k: np.asarray(v)[keep] for k, v in (alternatives or {}).items()}
    if len(views) < cfg.min_photos:
        raise CalibrationError(f"{len(views)} photos fit the board: at least "
                               f"{cfg.min_photos} needed")
    A = [_G(v.T_robot_flange, mount) for v in views]
    check_motion(A, cfg)
    max_out = int(np.floor(cfg.max_outlier_fraction * len(views)))
    agree = consistent_photos(A, C, cfg, max_out, declared=declared)
    if agree is None:     # as a whole: the checks name why (or let the fit judge)
        check_conventions(views, C, mount, alternatives, cfg, source)
        check_scale(A, C, cfg, source, units, declared=declared)
        agree = list(range(len(views)))
    for i in sorted(set(range(len(views))) - set(agree)):
        left[views[i].name] = ("its pose disagrees with the other photos' (the robot's turn "
                               "or motion to it is not the board's as the camera saw it): "
                               "a pose that is not this photo's, a board that moved on its "
                               "mount, or another board")
    views, A, C = [views[i] for i in agree], [A[i] for i in agree], [C[i] for i in agree]
    scale = check_scale(A, C, cfg, source, units, declared=declared)
    return _Prepared(views, solve_axzb(A, C), scale, left, pnp_px)


def _free(terms) -> np.ndarray:
    return np.array([n in ("fx", "fy", "cx", "cy") + tuple(terms) for n in LENS_NAMES])


def _heldout_px(views, mount, X0, Y0, lens0, free) -> float:
    """RMS (px, 2-D) of each photo predicted from a fit of the others (the errors alone:
    what a lens model is chosen by)."""
    R = refine(Problem(views, mount, X0, Y0, lens0, free))
    ss, n = 0.0, 0
    for k in range(len(views)):
        rk = refine(Problem(views[:k] + views[k + 1:], mount, R.X, R.Y, R.lens, free))
        one = Problem([views[k]], mount, rk.X, rk.Y, rk.lens, free)
        ss += float(np.sum((one.predict(one.start()) - one.px) ** 2))
        n += len(one.px)
    return float(np.sqrt(ss / n))


def _select_lens(views, mount, size_px, X0, Y0, cfg):
    """The undeclared lens's model chosen by the data: each of ``config.lens_models`` fitted
    with the rest, the one whose held-out photos are predicted best kept; (lens start,
    free terms, [(terms, held-out px)] of every model tried)."""
    tried = []
    for terms in (m.split() for m in cfg.lens_models.split(";")):
        lens0 = lens_start(views, size_px, terms)
        tried.append((" ".join(terms),
                      _heldout_px(views, mount, X0, Y0, lens0, _free(terms)), lens0))
    best = min(tried, key=lambda t: t[1])
    return best[2], _free(best[0].split()), [t[:2] for t in tried]


def fit_handeye(views, mount: str, size_px, *, lens=None, alternatives=None,
                source: str | None = None, units: str = "m",
                config: HandeyePhotosConfig | None = None) -> HandeyeFit:
    """The hand-eye of ``views`` (one :class:`View` a photo, in the photos' order) for a
    camera ``mount``ed ``fixed`` or on the ``arm``; ``lens`` (K, dist) when declared;
    ``alternatives`` (name -> (n, 4, 4)) the poses read under other conventions, to name
    one the data prefer. Raises ``VisionCalError`` for poses that contradict the photos,
    ``CalibrationError`` for what cannot be calibrated."""
    cfg = config or DEFAULT.handeye_photos
    if mount not in MOUNTS:
        raise VisionCalError(f"expected one of {', '.join(MOUNTS)}, got {mount!r}",
                             field="--mount")
    views = list(views)
    if len(views) < cfg.min_photos:
        raise CalibrationError(f"{len(views)} photos show the board: at least "
                               f"{cfg.min_photos} needed")
    declared = lens is not None
    if declared:
        lens0, free = lens_vector(np.asarray(lens[0], float), lens[1]), np.zeros(9, bool)
    else:       # the richest model's start for the photos' own poses
        richest = max(cfg.lens_models.split(";"), key=lambda m: len(m.split())).split()
        lens0 = lens_start(views, size_px, richest)
    prep = _prepare(views, mount, size_px, lens0, declared, alternatives, source, units, cfg)
    views, left = prep.views, dict(prep.left)
    X0, Y0 = prep.start.Z, prep.start.X       # G_i Y = X C_i: solve_axzb's X is our Y
    models: list = []
    j = None
    if not declared:
        lens0, free, models = _select_lens(views, mount, size_px, X0, Y0, cfg)
    max_out = int(np.floor(cfg.max_outlier_fraction * (len(views) + len(left))))
    while True:
        j = j or _judge(views, mount, X0, Y0, lens0, free, cfg.kinematic_length_rad)
        n = len(views)
        p_out = _outlier_p(j.heldout, cfg)
        worst = int(np.argmin(p_out))
        h = j.heldout[worst]
        if p_out[worst] >= cfg.outlier_alpha / n or len(left) >= max_out or n - 1 < cfg.min_photos:
            break
        left[h.name] = (f"predicted from the others {h.rms_px:.3g} px RMS off ({h.rms_mm:.3g} "
                        f"mm at the board), {h.stated_px:.2g} px expected (p = "
                        f"{h.p_value:.1g}): a pose that is not this photo's, a board that "
                        "moved on its mount, or another board")
        views = views[:worst] + views[worst + 1:]
        X0, Y0, lens0 = j.refined.X, j.refined.Y, j.refined.lens
        j = None
    ratio, p = _heldout_test(j.heldout)
    inflation = max(1.0, ratio)     # what is stated covers what held-out photos show
    R = j.refined
    resid = {v.name: float(np.sqrt(np.mean(np.sum(R.residual_px[R.view_of == i] ** 2, axis=1))))
             for i, v in enumerate(views)}
    shared = (None if j.shared is None else
              replace(j.shared, G=j.shared.G * inflation ** 2))
    return HandeyeFit(mount, R.X, R.Y, R.lens, free, declared, j.cov * inflation ** 2,
                      R.labels, tuple(views), left, resid, tuple(j.heldout), j.noise,
                      inflation, ratio, p, prep.start, prep.scale, prep.pnp_px,
                      tuple(int(s) for s in size_px), lens_models=tuple(models),
                      shared=shared)


def estimated_lens_fit(views, fit: HandeyeFit, *, alternatives=None, source=None,
                       units: str = "m", config: HandeyePhotosConfig | None = None
                       ) -> HandeyeFit | None:
    """The same photos with the lens estimated, to judge a declared one (``fit``'s); None
    when there are too few photos for it (2 x ``min_photos``) or it cannot be made."""
    cfg = config or DEFAULT.handeye_photos
    if len(views) < 2 * cfg.min_photos:
        return None
    try:
        return fit_handeye(views, fit.mount, fit.size_px, alternatives=alternatives,
                           source=source, units=units, config=cfg)
    except VisionCalError:
        return None
