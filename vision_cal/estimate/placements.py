"""One robot from several sheet placements (``vision-cal calibrate A/ B/ C/ --joint``).

The robot stays where it is; the sheet is taped down in two or three places (or several
sheets are used), one dataset folder each. Everything is written in the robot frame R of
the contract ("The robot frame and cameras"): origin on the joint-1 axis, x along link 1 at
commanded ``q1 = 0``. In R the base model has ``base = 0`` and ``z1 = 0``; placement ``k``
is a sheet pose, ``p_S = b_k + Rot(a_k) p_R``, so on its own sheet placement ``k`` is the
usual model with ``z1 = a_k`` and ``base = b_k``. Shared by all placements: ``L1``, ``L2``,
``z2`` and every effect (a tool and joint-4 effects included, joints ``(N, 3)``).

The flat vector is ``[L1, L2, z2, (a_k, bx_k, by_k) for each placement, effects...]``
(mm, rad). A joint-1 error that is once per turn (``joint_cyclic`` harmonic 1) looks over
the ~135 deg one sheet spans almost like a constant (``a_k``) plus a slope
(``joint_scale``); over the combined range of three placements it does not.

Effects are chosen by the estimator's one forward selection
(:mod:`vision_cal.estimate.forward`), the placements posed as its problem
(:func:`fit_placements`): significant (F-test at ``alpha`` over the dictionary's columns),
BIC down and the cross-validated error down, at most ``max_effects``, no joint-term
alternative better.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np
from scipy import stats

from vision_cal.model import joint_terms as jt
from vision_cal.model.lsq import FailedFit, Fit
from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.dataset.covariance import covariance_json
from vision_cal.dataset.nominal import nominal_blocks
from vision_cal.dataset.valid_for import build as valid_for_block
from vision_cal.errors import CalibrationError
from vision_cal.estimate.candidates import Candidate, default_candidates
from vision_cal.estimate.forward import Problem, Trial, forward_select
from vision_cal.estimate.marks import MarkData
from vision_cal.estimate.verdict import judge_placements
from vision_cal.model.kinematics import ScaraParams
from vision_cal.model.robot import (Effect, JointBacklash, JointCyclic, JointScale, JointTerms,
                              RobotModel, SheetAffine, Tool)
from vision_cal.model.rms import rms_2d
from vision_cal.model.tool_fit import joint4_values
from vision_cal.model.solve import solve


@dataclass(frozen=True)
class Placement:
    """One placement's marks. Arrays over its N marks."""

    name: str
    q_deg: np.ndarray          # (N, 2) or (N, 3) with joint 4
    xy_mm: np.ndarray          # (N, 2) sheet mm
    approach: np.ndarray       # (N, 2) or (N, 3)
    sigma_mm: np.ndarray | None = None   # (N,) measurement std, when known


def shared_candidates() -> list[Candidate]:
    """The effects tried on the combined marks: the estimator's one list
    (:func:`vision_cal.estimate.candidates.default_candidates`) but a sheet's
    (``sheet_affine`` is one placement's paper, not the shared robot's)."""
    return [c for c in default_candidates() if not isinstance(c.effect, SheetAffine)]


@dataclass(frozen=True)
class PlacementsFit:
    """Shared robot and per-placement sheet poses, with the covariance of the flat vector."""

    shared: ScaraParams                   # in R: z1 = 0, base = 0
    effects: tuple[Effect, ...]
    poses: tuple[tuple[float, float, float], ...]   # (a_deg, bx_mm, by_mm) per placement
    cov: np.ndarray
    labels: tuple[str, ...]
    names: tuple[str, ...]
    residuals_mm: tuple[np.ndarray, ...]  # (N_k, 2) per placement
    ssr: float                            # weighted
    dof: int

    def model_on(self, k: int) -> RobotModel:
        """Placement ``k``'s model in its sheet frame (z1 = a_k, base = b_k)."""
        a, bx, by = self.poses[k]
        p = self.shared
        return RobotModel(ScaraParams(p.L1_mm, p.L2_mm, a, p.z2_deg, bx, by), self.effects)

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov), 0.0, None))

    def effect_std(self, k: int) -> np.ndarray:
        start = 3 + 3 * len(self.poses) + sum(len(e.theta) for e in self.effects[:k])
        return self.std[start:start + len(self.effects[k].theta)]

    @property
    def rms_mm(self) -> float:
        return rms_2d(np.concatenate(self.residuals_mm))


def _vector(shared: ScaraParams, poses, effects) -> np.ndarray:
    v = [shared.L1_mm, shared.L2_mm, np.radians(shared.z2_deg)]
    for a, bx, by in poses:
        v += [np.radians(a), bx, by]
    return np.concatenate([np.array(v)] + [e.theta for e in effects])


def _unpack(v, n_place: int, effects):
    shared = ScaraParams(float(v[0]), float(v[1]), 0.0, float(np.degrees(v[2])))
    poses = tuple((float(np.degrees(v[3 + 3 * k])), float(v[4 + 3 * k]), float(v[5 + 3 * k]))
                  for k in range(n_place))
    rest = v[3 + 3 * n_place:]
    out, i = [], 0
    for e in effects:
        n = len(e.theta)
        out.append(e.with_theta(rest[i:i + n]))
        i += n
    return shared, poses, tuple(out)


def _weights(places: list[Placement]) -> list[np.ndarray]:
    return [np.ones(len(p.xy_mm)) if p.sigma_mm is None else 1.0 / p.sigma_mm for p in places]


def _full_jacobian(places: list[Placement], models: list[RobotModel], w) -> np.ndarray:
    """Weighted Jacobian rows (2 N_total, 3 + 3 n_place + n_eff) of the flat vector, from
    each placement's model (its sheet frame) and weights ``w`` (per placement, (N_k,))."""
    n_place = len(places)
    P = 3 + 3 * n_place + len(models[0].vector) - 6
    rows = []
    for k, (m, p, wk) in enumerate(zip(models, places, w)):
        J = m.jacobian(p.q_deg, p.approach) * wk[:, None, None]   # (N, 2, 6 + n_eff)
        full = np.zeros((len(p.xy_mm), 2, P))
        full[:, :, 0], full[:, :, 1], full[:, :, 2] = J[:, :, 0], J[:, :, 1], J[:, :, 3]
        full[:, :, 3 + 3 * k] = J[:, :, 2]
        full[:, :, 4 + 3 * k] = J[:, :, 4]
        full[:, :, 5 + 3 * k] = J[:, :, 5]
        full[:, :, 3 + 3 * n_place:] = J[:, :, 6:]
        rows.append(full.reshape(-1, P))
    return np.concatenate(rows)


def _solve(places: list[Placement], shared, poses, effects,
           condition_limit: float) -> PlacementsFit:
    n_place = len(places)
    w = _weights(places)
    n_eff = sum(len(e.theta) for e in effects)
    P = 3 + 3 * n_place + n_eff

    def models(v):
        sh, po, ef = _unpack(v, n_place, effects)
        return [RobotModel(ScaraParams(sh.L1_mm, sh.L2_mm, a, sh.z2_deg, bx, by), ef)
                for a, bx, by in po]

    def fun(v):
        return np.concatenate([((m.predict(p.q_deg, p.approach) - p.xy_mm) * wk[:, None]).ravel()
                               for m, p, wk in zip(models(v), places, w)])

    def jac(v):
        return _full_jacobian(places, models(v), w)

    v0 = _vector(shared, poses, effects)
    n_rows = 2 * sum(len(p.xy_mm) for p in places)
    if n_rows <= P:
        raise CalibrationError(f"{n_rows // 2} marks over {n_place} placements give {n_rows} "
                               f"equations for {P} unknowns: more marks are needed")
    sol = solve(fun, v0, jac=jac)
    if not sol:
        raise CalibrationError(f"the placements' fit: {sol.reason}")
    labels = tuple(["L1_mm", "L2_mm", "z2"] + [f"{p.name}.{x}" for p in places
                                               for x in ("a", "base_x_mm", "base_y_mm")]
                   + [f"{e.label}.{n}" for e in effects for n in e.param_names])
    cov = sol.covariance(labels, cond_limit=condition_limit)  # config fit.condition_number_limit
    if cov.not_fixed:
        raise CalibrationError("the placements cannot tell the shared parameters apart ("
                               f"{cov.reason()})")
    sh, po, ef = _unpack(sol.x, n_place, effects)
    res = tuple(p.xy_mm - m.predict(p.q_deg, p.approach) for m, p in zip(models(sol.x), places))
    return PlacementsFit(sh, ef, po, cov.matrix, labels, tuple(p.name for p in places), res,
                         sol.ssr, sol.dof)


def _start(places: list[Placement], tool: Tool | None) -> tuple[ScaraParams, tuple]:
    """Each placement fitted alone (base model, and the tool when given): shared lengths and
    z2 averaged, each sheet pose from its own fit."""
    fits = []
    for p in places:
        model = RobotModel(ScaraParams(1.0, 1.0), (tool,)) if tool is not None else None
        fits.append(Fit.from_estimate(p.q_deg, p.xy_mm, approach=p.approach, model=model,
                                      sigma_mm=p.sigma_mm, robust=False).or_raise().params)
    shared = ScaraParams(float(np.mean([f.L1_mm for f in fits])),
                         float(np.mean([f.L2_mm for f in fits])), 0.0,
                         float(np.degrees(np.angle(np.mean(np.exp(1j * np.radians(
                             [f.z2_deg for f in fits])))))))
    return shared, tuple((f.z1_deg, f.base_x_mm, f.base_y_mm) for f in fits)


def _library_columns(e: Effect) -> tuple[tuple[int, str], ...] | None:
    """The dictionary columns (joint, feature) a joint-1/2 library effect is (None for
    others): ``joint_scale`` is ``q_j``, ``joint_backlash`` ``approach_j``, ``joint_cyclic``
    the sine and cosine of its harmonic (:data:`vision_cal.model.joint_terms.DICTIONARY`)."""
    j = getattr(e, "joint", None)
    if j not in (1, 2):
        return None
    if isinstance(e, JointScale):
        return ((j, f"q{j}"),)
    if isinstance(e, JointBacklash):
        return ((j, f"approach{j}"),)
    if isinstance(e, JointCyclic):
        a = f"q{j}" if e.harmonic == 1 else f"{e.harmonic}*q{j}"
        return ((j, f"sin({a})"), (j, f"cos({a})"))
    return None


def best_alternative(places: list[Placement], fit: PlacementsFit, effect: Effect):
    """Issue 17's rule for a library ``effect`` about to be added to ``fit``: the subset of
    the joint-term dictionary (both joints' columns of :data:`vision_cal.model.joint_terms.
    DICTIONARY`) with as many parameters that explains most of ``fit``'s residual, to first
    order (the columns' displacements with what ``fit`` already absorbs projected out).

    Returns ``(columns, drop, library_drop)``: the best subset ``((joint, feature), ...)``,
    the weighted residual sum of squares it removes and what the effect's own columns
    remove; ``None`` when the effect has no dictionary columns (joint 4, the sheet)."""
    lib = _library_columns(effect)
    if lib is None:
        return None
    names = [(j, f) for j in (1, 2) for f in jt.DICTIONARY]
    terms = tuple(JointTerms(joint=j, features=jt.DICTIONARY) for j in (1, 2))
    models = [RobotModel(m.params, m.effects + terms)
              for m in (fit.model_on(k) for k in range(len(places)))]
    w = _weights(places)
    J = _full_jacobian(places, models, w)
    n_dict = len(names)
    Jm, X = J[:, :-n_dict], J[:, -n_dict:]
    Q, _ = np.linalg.qr(Jm)
    X = X - Q @ (Q.T @ X)
    y = np.concatenate([(r * wk[:, None]).ravel() for r, wk in zip(fit.residuals_mm, w)])
    norms = np.linalg.norm(X, axis=0)
    usable = norms > 1e-8 * norms.max()

    def drop(idx) -> float:
        """What the columns ``idx`` explain of ``y``: ``|projection of y|^2``."""
        Xi = X[:, list(idx)]
        return float(y @ (Xi @ np.linalg.lstsq(Xi, y, rcond=None)[0]))

    ok = [i for i in range(n_dict) if usable[i]]
    best, best_drop = None, -np.inf
    for idx in itertools.combinations(ok, len(lib)):
        d = drop(idx)
        if d > best_drop:
            best, best_drop = idx, d
    lib_drop = drop([names.index(c) for c in lib])
    return tuple(names[i] for i in best), best_drop, lib_drop


def cv_residuals(places: list[Placement], fit: PlacementsFit, effects, k_folds: int,
                 condition_limit: float, rng_seed: int = 0) -> list[np.ndarray] | None:
    """k-fold cross-validated residuals (per placement (N_k, 2), mm) of the shared model
    with ``effects``: the marks of every placement split into ``k_folds`` folds (fixed
    seed: the same data calibrate the same way), each fold predicted by the fit on the
    others (started from ``fit``). None when a fold cannot be fitted."""
    rng = np.random.default_rng(rng_seed)
    fold_of = [rng.permutation(len(p.xy_mm)) % k_folds for p in places]
    out = [np.full((len(p.xy_mm), 2), np.nan) for p in places]
    for f in range(k_folds):
        train = [Placement(p.name, p.q_deg[fo != f], p.xy_mm[fo != f], p.approach[fo != f],
                           None if p.sigma_mm is None else p.sigma_mm[fo != f])
                 for p, fo in zip(places, fold_of)]
        try:
            t = _solve(train, fit.shared, fit.poses, effects, condition_limit)
        except CalibrationError:
            return None
        for k, (p, fo) in enumerate(zip(places, fold_of)):
            if np.any(fo == f):
                out[k][fo == f] = p.xy_mm[fo == f] - t.model_on(k).predict(
                    p.q_deg[fo == f], p.approach[fo == f])
    return out


class _PlacementsProblem(Problem):
    """Several placements posed to the forward selection
    (:mod:`vision_cal.estimate.forward`): the shared lengths, ``z2`` and effects free with
    one sheet pose per placement (:func:`_solve`), the weighted residual sum of squares and
    degrees of freedom of that solve, the k-fold cross-validated error over every
    placement's marks as the held-out error, trials ranked by p then F; an effect vetoed
    when a joint-term alternative with as many parameters removes significantly more of
    the residual (:func:`best_alternative`)."""

    def __init__(self, places: list[Placement], alpha_each: float, k_folds: int,
                 condition_limit: float):
        self.places, self.alpha_each = places, alpha_each
        self.k_folds, self.limit = k_folds, condition_limit
        self.n_obs = 2 * sum(len(p.xy_mm) for p in places)

    def fit_with(self, current: PlacementsFit, c: Candidate):
        try:
            return _solve(self.places, current.shared, current.poses,
                          current.effects + (c.effect,), self.limit)
        except CalibrationError as e:
            return FailedFit(e.reason)

    def rss(self, fit: PlacementsFit) -> float:
        return fit.ssr

    def n_params(self, fit: PlacementsFit) -> int:
        return len(fit.cov)

    def dof(self, fit: PlacementsFit) -> int:
        return fit.dof

    def held(self, fit: PlacementsFit) -> float:
        """The k-fold cross-validated RMS (mm, 2-D, :func:`cv_residuals`); NaN when a fold
        cannot be fitted."""
        res = cv_residuals(self.places, fit, fit.effects, self.k_folds, self.limit)
        return float("nan") if res is None else rms_2d(np.concatenate(res))

    def order(self, trials: list) -> list:
        return sorted(trials, key=lambda t: (t.p, -t.F))

    def veto(self, current: PlacementsFit, t: Trial):
        """The joint-term columns that beat ``t``'s effect (its excess drop over the
        effect's own, in units of the residual variance, significant at ``alpha_each``), or
        None."""
        alt = best_alternative(self.places, current, t.candidate.effect)
        beaten = alt is not None and (alt[1] - alt[2]) / (t.fit.ssr / t.fit.dof) > \
            stats.f.isf(self.alpha_each, 1, t.fit.dof)
        return alt[0] if beaten else None


def fit_placements(places: list[Placement], *, candidates=None, tool: Tool | None = None,
                   config: EstimatorConfig | None = None) -> tuple[PlacementsFit, list]:
    """The shared robot from every placement, effects chosen by the estimator's one forward
    selection (:func:`vision_cal.estimate.forward.forward_select`) posed as
    :class:`_PlacementsProblem`: a candidate (:func:`shared_candidates`, or ``candidates``)
    is kept when its F-test passes at ``alpha / max(n_candidates, the dictionary's
    columns)`` (``alpha``, ``max_effects`` and ``k_folds``: ``config.selection``, default
    ``DEFAULT``), the BIC drops *and* the k-fold cross-validated error over the marks of
    every placement goes down; among those, the one with the lowest cross-validated error
    that no joint-term alternative beats. An F-test alone claimed an extra ``joint_scale``
    beside a true once-per-turn error in about 1 of 200 clean-noise datasets
    (bench/tool_joint4.py, seed 1502).

    Returns the fit and the selection log (one dict per candidate ranked in a round: F, p,
    delta BIC, cross-validated RMS before and after, accepted, the alternative that beat
    it; a round where none passed logs its most significant candidate)."""
    if len(places) < 1:
        raise CalibrationError("no placement given")
    config = config or DEFAULT
    alpha, max_effects, k_folds = (config.selection.alpha, config.selection.max_effects,
                                   config.selection.k_folds)
    limit = config.fit.condition_number_limit
    shared, poses = _start(places, tool)
    base_effects = (tool,) if tool is not None else ()
    fit = _solve(places, shared, poses, base_effects, limit)
    cands = list(shared_candidates() if candidates is None else candidates)
    # claimed against every column of the joint-term dictionary, so tested at the level the
    # dictionary's own selection uses (alpha split over its columns, vision_cal.estimate.
    # discover): alpha / n_candidates alone let an F-test claim a joint_scale that q1^3 or
    # q1*q2 explain as well (1 in 200 datasets, bench/tool_joint4.py seed 1502)
    alpha_each = alpha / max(len(cands), 2 * len(jt.DICTIONARY))
    problem = _PlacementsProblem(places, alpha_each, k_folds, limit)
    rounds, fit, _ = forward_select(problem, fit, cands, alpha_each=alpha_each,
                                    max_effects=max_effects)
    log = []
    for r in rounds:
        ranked = [(t, cv, alt) for t, cv, alt in r.vetoed] + (
            [(*r.chosen, None)] if r.chosen is not None else [])
        for t, cv, alt in ranked:
            log.append({"effect": t.candidate.label, "F": t.F, "p_value": t.p,
                        "delta_bic": t.dbic, "cv_rms_mm": [r.held, cv],
                        "accepted": alt is None,
                        **({"alternative": [f"{f} (joint {j})" for j, f in alt]}
                           if alt is not None else {})})
        if not ranked:           # none passed: the most significant, not accepted
            t = r.trials[0]
            log.append({"effect": t.candidate.label, "F": t.F, "p_value": t.p,
                        "delta_bic": t.dbic, "cv_rms_mm": [r.held, None], "accepted": False})
    return fit, log


def unexplained_seen(log) -> list[str]:
    """Sentences for the selection rounds where a significant library effect was not
    claimed because joint-term columns with as many parameters explain significantly more
    (the structure is there; no library effect says what it is)."""
    return [f"the residual follows {' + '.join(r['alternative'])} significantly better than "
            f"{r['effect']} (F = {r['F']:.1f}, p = {r['p_value']:.2g}), which no library "
            "effect models" for r in log if r.get("alternative")]


def robot_frame_json(fit: PlacementsFit, names) -> dict:
    """calibration.json's part for a multi-placement calibration: ``params`` in the robot
    frame R (``joint_zero_deg[0] = 0``, ``base_mm = [0, 0]``), ``std``, ``effects``,
    ``placements`` (each sheet's pose: ``p_S = base_mm + Rot(angle_deg) p_R``, with std)."""
    s = fit.std
    sh = fit.shared
    params = {"L1_mm": sh.L1_mm, "L2_mm": sh.L2_mm, "joint_zero_deg": [0.0, sh.z2_deg],
              "base_mm": [0.0, 0.0]}
    std = {"L1_mm": float(s[0]), "L2_mm": float(s[1]),
           "joint_zero_deg": [0.0, float(np.degrees(s[2]))], "base_mm": [0.0, 0.0]}
    effects = []
    for k, e in enumerate(fit.effects):
        if isinstance(e, Tool):
            params["tool_mm"] = list(e.tool_mm)
            std["tool_mm"] = fit.effect_std(k).tolist()
        else:
            effects.append(e.to_json(fit.effect_std(k)))
    placements = []
    for k, name in enumerate(names):
        a, bx, by = fit.poses[k]
        i = 3 + 3 * k
        placements.append({"folder": str(name), "angle_deg": a, "base_mm": [bx, by],
                           "std": {"angle_deg": float(np.degrees(s[i])),
                                   "base_mm": [float(s[i + 1]), float(s[i + 2])]},
                           "residual_rms_mm": rms_2d(fit.residuals_mm[k]),
                           "n_marks": int(len(fit.residuals_mm[k]))})
    return {"frame": "robot", "params": params, "std": std, "effects": effects,
            "placements": placements, "residual_rms_mm": {"final_model": fit.rms_mm}}


def placement_cov(fit: PlacementsFit, k: int) -> np.ndarray:
    """Covariance of placement ``k``'s model vector (``fit.model_on(k).vector`` order)."""
    n = len(fit.poses)
    idx = [0, 1, 3 + 3 * k, 2, 4 + 3 * k, 5 + 3 * k] + list(range(3 + 3 * n, len(fit.cov)))
    return fit.cov[np.ix_(idx, idx)]


# --------------------------------------------------------------------------- the calibrations

def _mark_json(place: Placement, j: int, xy, r) -> dict:
    """A placement calibration's ``marks`` entry: where it was measured, its residual under
    the shared robot, its command and approach, its noise when measured by camera."""
    d = {"measured_mm": xy.tolist(), "residual_mm": r.tolist(), "role": "calibration",
         "joints_deg": [float(v) for v in place.q_deg[j, :2]],
         "approach": [int(v) for v in place.approach[j, :2]]}
    if place.q_deg.shape[1] == 3:
        d["j4_deg"] = float(place.q_deg[j, 2])
    if place.sigma_mm is not None:
        d["sigma_mm"] = float(place.sigma_mm[j])
    return d


def _verdicts(places: list[Placement], sessions, fit: PlacementsFit, log,
              config: EstimatorConfig):
    """The contract's verdict of the joint fit and of each placement, and each placement's
    agreement with the others (:func:`vision_cal.estimate.verdict.judge_placements`): the
    residuals under the shared robot, the k-fold held-out ones, the robot block's
    repeatability (the first session that gives one)."""
    held = cv_residuals(places, fit, fit.effects, config.selection.k_folds,
                         config.fit.condition_number_limit)
    if held is None:
        held = [np.full((len(p.xy_mm), 2), np.nan) for p in places]
    rep = next((s.robot.repeatability_mm for s in sessions
                if s.robot.repeatability_mm is not None), None)
    seen = unexplained_seen(log)
    reasons = [("check", "structure no candidate explains is left in the residual ("
                + "; ".join(seen) + ")")] if seen else []
    return judge_placements([p.name for p in places], list(fit.residuals_mm),
                            [p.sigma_mm for p in places], held, n_params=len(fit.cov),
                            repeatability_mm=rep, reasons=reasons, config=config.verdict)


def placement_of(name: str, cal: MarkData) -> Placement:
    """A placement's calibration marks (:class:`~vision_cal.estimate.marks.MarkData`), joint 4
    in the joints when the session gives it."""
    q, a = cal.q_deg, cal.approach
    if cal.joint4 is not None:
        q = np.column_stack([q, cal.joint4[:, 0]])
        a = np.column_stack([a, cal.joint4[:, 1]])
    return Placement(name, q, cal.xy_mm, a, cal.sigma_mm)


def calibrate_placed(names, sessions, cals: list[MarkData],
                     config: EstimatorConfig = DEFAULT
                     ) -> tuple[CalibrationResult, list[CalibrationResult]]:
    """One robot from several placements (``calibrate --joint``).

        robot_frame, per_placement = calibrate_placed(["place0", "place1"], sessions, cals)

    The estimator's problem:
    each placement's calibration marks (``cals``, with its ``sessions`` and sub-folder
    ``names``) fitted together (:func:`fit_placements`), judged (:func:`_verdicts`), and
    the calibrations: the robot frame's (R) and each placement's in its sheet frame (for
    ``plan``)."""
    places = [placement_of(n, c) for n, c in zip(names, cals)]
    with_j4 = [p for p in places if p.q_deg.shape[1] == 3]
    if with_j4 and len(with_j4) != len(places):
        raise CalibrationError("some placements give j4_deg and others do not: give it in "
                               "every session.json or in none")
    tool = None
    if with_j4 and len(joint4_values(np.concatenate([p.q_deg[:, 2] for p in places]))) > 1:
        tool = Tool()
    fit, log = fit_placements(places, tool=tool, config=config)
    joint_v, place_v, agree = _verdicts(places, sessions, fit, log, config)
    rf = robot_frame_json(fit, names)
    effects = list(rf["effects"])
    seen = unexplained_seen(log)
    if seen:   # significant structure that a library effect would only stand in for
        effects.append({"name": "unexplained", "seen": seen})
    for pl, v, a in zip(rf["placements"], place_v, agree):
        pl["verdict"] = v.to_json()
        if a is not None:
            pl["agreement"] = a.to_json()
    joint = CalibrationResult(
        method="lsq-placements", params=rf["params"], std=rf["std"], effects=tuple(effects),
        residual_rms_mm=rf["residual_rms_mm"],
        diagnosis={"selection": log, "alpha": config.selection.alpha},
        config=config.to_json(),
        covariance=covariance_json(list(fit.labels), fit.cov),
        notes=("one robot from several placements: params in the robot frame R "
               "(docs/format.md); each placement's sheet-frame calibration in its "
               "sub-folder",),
        verdict=joint_v.to_json(),
        extra={"frame": rf["frame"], "placements": rf["placements"]})
    subs = []
    for k, (session, cal) in enumerate(zip(sessions, cals)):
        m = fit.model_on(k)
        params = m.params.to_json()
        if m.tool is not None:
            params["tool_mm"] = list(m.tool.tool_mm)
        placement = rf["placements"][k]
        sub = CalibrationResult(
            method="lsq-placements", params=params,
            effects=tuple(rf["effects"]),     # the shared robot's, without the unexplained
            covariance=covariance_json(m.param_labels(), placement_cov(fit, k)),
            # the robot file the controller runs (dataset/nominal), not the pilot's model
            **nominal_blocks(session.raw, session.robot.params.to_json()),
            home_deg=tuple(float(v) for v in session.robot.home_deg),
            residual_rms_mm={"final_model": placement["residual_rms_mm"]},
            verdict=place_v[k].to_json(),
            marks={i: _mark_json(places[k], j, xy, r)
                   for j, (i, xy, r) in enumerate(zip(cal.ids, cal.xy_mm,
                                                      fit.residuals_mm[k]))},
            extra={"placement": placement})
        # what plan checks its targets against
        sub = replace(sub, valid_for=valid_for_block(sub))
        subs.append(sub)
    return joint, subs
