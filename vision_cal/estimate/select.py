"""Residuals traced to effects: forward selection with held-out evidence.

Start from the base model. Each round fits the current model plus each candidate
(:mod:`vision_cal.estimate.candidates`) that the plan can identify, and keeps the one
that most lowers the held-out error (validation marks when there are at least three,
else k-fold cross-validation over the calibration marks), provided

- the gain is significant: an F-test of the drop in the residual sum of squares at level
  ``alpha / n_candidates`` (Bonferroni, so clean data claims nothing), and BIC drops; and
- the held-out error goes down.

It repeats until nothing helps. Candidates the plan cannot tell apart from the base
model (backlash with one approach direction) are reported as not identifiable with the
plan change that would fix it. Structure left in the residual (joint-angle residuals that
depend on angle or approach beyond chance) with no candidate to explain it is reported
as ``unexplained``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy import stats

from vision_cal.model.lsq import FailedFit, Fit
from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.estimate.candidates import Candidate, default_candidates, joint_residuals_deg
from vision_cal.estimate.forward import Problem, Trial, forward_select
from vision_cal.estimate.structure import harmonic_scan, sheet_scan
from vision_cal.model.kinematics import ScaraParams
from vision_cal.model.robot import JointCyclic, RobotModel, SheetAffine, Tool
from vision_cal.model.rms import rms, rms_2d



@dataclass(frozen=True)
class Evidence:
    """What one candidate did to the fit, in one round."""

    label: str
    heldout_before_mm: float
    heldout_after_mm: float
    rss_before: float
    rss_after: float
    F: float
    p_value: float
    delta_bic: float
    accepted: bool
    reason: str
    effect: dict | None = None

    def to_json(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass(frozen=True)
class Diagnosis:
    base_fit: Fit
    final_fit: Fit
    accepted: tuple[Evidence, ...]
    rejected: tuple[Evidence, ...]
    not_identifiable: tuple[dict, ...]
    unexplained: dict | None
    heldout_kind: str
    heldout_base_mm: float
    heldout_final_mm: float
    analysis: dict = field(default_factory=dict)
    thresholds: dict = field(default_factory=dict)  # the tests' levels, for the report

    def effects_json(self) -> list[dict]:
        """calibration.json ``effects`` entries of the final model (with std)."""
        fit = self.final_fit
        out, k = [], 6
        for e in fit.model.effects:
            n = len(e.theta)
            if isinstance(e, Tool):   # params.tool_mm, not an effect (contract)
                k += n
                continue
            d = e.to_json(fit.std[k:k + n])
            ev = next((a for a in self.accepted if a.label == e.label), None)
            if ev is not None:
                d["evidence"] = {"heldout_rms_mm": [ev.heldout_before_mm, ev.heldout_after_mm],
                                 "F": ev.F, "p_value": ev.p_value, "delta_bic": ev.delta_bic}
            out.append(d)
            k += n
        if self.unexplained:
            out.append({"name": "unexplained", **self.unexplained})
        return out


def _fit(model, q, xy, app, sigma, ids, config: EstimatorConfig) -> Fit | FailedFit:
    return Fit.from_estimate(q, xy, approach=app, model=model, sigma_mm=sigma, ids=ids,
                             config=config)


def heldout_rms(model: RobotModel, q, xy, app, *, sigma=None, q_val=None, xy_val=None,
                app_val=None, k_folds: int = 5, rng=None,
                config: EstimatorConfig | None = None, fit: Fit | None = None) -> float:
    """Held-out RMS (mm, 2-D): on validation marks if given, else k-fold CV (NaN when a
    fold's marks cannot fit ``model``: no held-out error can be given then). ``fit``: the
    robust fit of ``model`` to these very marks when the caller has it (the validation
    marks are then predicted from it instead of fitting it again; k-fold ignores it)."""
    if q_val is not None and len(q_val) >= 3:
        # fitted as the calibration is (robust pass): a mark it leaves out as an outlier
        # (a mis-associated dot) would pull every model alike and hide what an effect does
        f = fit or Fit.from_estimate(q, xy, approach=app, model=model, sigma_mm=sigma,
                                     robust=True, config=config).or_raise()
        r = xy_val - f.predict(q_val, app_val)
        return rms_2d(r)
    n = len(q)
    # folds from a fixed seed unless one is given: the same data calibrate the same way
    rng = np.random.default_rng(0 if rng is None else rng)
    folds = np.array_split(rng.permutation(n), min(k_folds, n))
    err = []
    for idx in folds:
        keep = np.ones(n, dtype=bool)
        keep[idx] = False
        f = Fit.from_estimate(q[keep], xy[keep], approach=app[keep], model=model,
                              sigma_mm=None if sigma is None else sigma[keep], robust=False,
                              config=config)
        if not f:
            return float("nan")
        err.append(xy[idx] - f.predict(q[idx], app[idx]))
    return rms_2d(np.concatenate(err))


def residual_analysis(fit: Fit, q, app, *, n_bins: int = 6) -> dict:
    """Joint-angle residuals split by approach and binned against each joint angle."""
    keep = fit.inliers
    dq = joint_residuals_deg(fit.model, q, app, fit.residuals_mm)
    out = {}
    for j in range(2):
        d, a, qq = dq[keep, j], app[keep, j], q[keep, j]
        ok = np.isfinite(d)
        d, a, qq = d[ok], a[ok], qq[ok]
        res = {"rms_deg": rms(d)}
        if (a > 0).sum() >= 2 and (a < 0).sum() >= 2:
            t = stats.ttest_ind(d[a > 0], d[a < 0], equal_var=False)
            res["by_approach_deg"] = {"+1": float(d[a > 0].mean()), "-1": float(d[a < 0].mean()),
                                      "t": float(t.statistic), "p_value": float(t.pvalue)}
        if len(d) >= 2 * n_bins:
            edges = np.quantile(qq, np.linspace(0, 1, n_bins + 1))
            b = np.clip(np.searchsorted(edges, qq, side="right") - 1, 0, n_bins - 1)
            means = np.array([d[b == i].mean() for i in range(n_bins)])
            counts = np.array([(b == i).sum() for i in range(n_bins)])
            s2 = np.var(d, ddof=1) if len(d) > 1 else np.nan
            chi2 = float(np.sum(counts * (means - d.mean()) ** 2) / s2) if s2 > 0 else 0.0
            res["by_angle"] = {"bin_center_deg": ((edges[:-1] + edges[1:]) / 2).tolist(),
                               "mean_deg": means.tolist(), "chi2": chi2,
                               "p_value": float(stats.chi2.sf(chi2, n_bins - 1))}
        out[f"joint{j + 1}"] = res
    return out


def diagnose(q_deg, xy_mm, approach=None, *, sigma_mm=None, ids=None, q_val=None, xy_val=None,
             approach_val=None, candidates: list[Candidate] | None = None,
             alpha: float | None = None, k_folds: int | None = None,
             max_effects: int | None = None, rng=None, base_effects: tuple = (),
             config: EstimatorConfig | None = None) -> Diagnosis:
    """Calibrate the base model, then add the effects the residual asks for. Thresholds:
    ``config`` (default ``vision_cal.config.DEFAULT``); ``alpha``, ``k_folds`` and
    ``max_effects`` given here win over its ``selection`` part.

    ``base_effects``: effects every model holds and the selection never tests (the tool and
    joint-4 effects: joints ``(N, 3)`` ``[q1, q2, q4]`` and approach ``(N, 3)``, contract
    "Joint 4 and the tool"); the tool is reported in ``params``, not among the effects.

    The stages: the selection on every mark (:meth:`_Problem.select_on`), again away from
    marks that share a residual (:func:`_away_from_local`), the reported model's fit
    (:func:`_reported`) and what its residual still shows (:func:`_final_analysis`)."""
    pb = _problem(q_deg, xy_mm, approach, sigma_mm=sigma_mm, ids=ids, q_val=q_val,
                  xy_val=xy_val, approach_val=approach_val, candidates=candidates, alpha=alpha,
                  k_folds=k_folds, max_effects=max_effects, rng=rng, base_effects=base_effects,
                  config=config or DEFAULT)
    base = _fit(pb.base_model, pb.q, pb.xy, pb.app, pb.sigma, pb.ids, pb.config).or_raise()
    found = pb.select_on(np.ones(len(pb.q), dtype=bool))
    found, sheet_map = _away_from_local(pb, found, base)
    current = _reported(pb, base, found)
    # keep only the last round's rejections per label (the final word on each candidate)
    last = {}
    for ev in found.selection.rejected:
        last[ev.label] = ev
    sheet_alpha = pb.alpha / 2
    analysis = _final_analysis(pb, current.fit, sheet_map)
    unexplained = _unexplained(analysis, pb.alpha, found.harmonics, sheet_alpha)
    kind = ("validation marks" if pb.has_val
            else f"{min(pb.k_folds, len(pb.q))}-fold cross-validation")
    return Diagnosis(base, current.fit, tuple(found.selection.accepted), tuple(last.values()),
                     tuple(found.selection.not_identifiable), unexplained, kind,
                     current.base_held, current.held, analysis,
                     {"alpha": pb.alpha, "n_candidates": len(pb.cands),
                      "alpha_each": pb.alpha_each, "delta_bic_below": 0.0,
                      "k_folds": pb.k_folds, "max_effects": pb.max_effects,
                      "unexplained_harmonics_alpha": pb.alpha,
                      "unexplained_sheet_alpha": sheet_alpha})


@dataclass(frozen=True)
class _Found:
    """A selection (:class:`_Selection`) with the joint harmonics no candidate offers
    found in the residual (the scan's rows) and fitted as nuisances (their effects)."""

    selection: "_Selection"
    harmonics: list
    nuisance: tuple


@dataclass(frozen=True)
class _Problem:
    """One diagnosis's data and levels: the calibration marks (``q`` (N, 2|3), ``xy``,
    ``app``, ``sigma`` or None, ``ids`` as given), the validation marks (used when
    ``has_val``: at least three), the candidates and the selection's thresholds."""

    q: np.ndarray
    xy: np.ndarray
    app: np.ndarray
    sigma: np.ndarray | None
    ids: object
    q_val: np.ndarray | None
    xy_val: np.ndarray | None
    app_val: np.ndarray | None
    has_val: bool
    cands: list
    alpha: float
    alpha_each: float           # alpha over the candidates (Bonferroni)
    k_folds: int
    max_effects: int
    rng: object
    base_model: RobotModel | None
    n_base: int                 # effects every model holds (the tool's, joint 4's)
    min_sheet_marks: int
    config: EstimatorConfig

    def held_on(self, sub):
        """The held-out RMS of a model fitted to the marks ``sub``
        (:func:`heldout_rms`: the validation marks, else k-fold CV over ``sub``)."""
        q, xy, app, sigma = self.q, self.xy, self.app, self.sigma

        def held(model, fit=None):
            return heldout_rms(model, q[sub], xy[sub], app[sub],
                               sigma=None if sigma is None else sigma[sub],
                               q_val=self.q_val if self.has_val else None, xy_val=self.xy_val,
                               app_val=self.app_val, k_folds=self.k_folds, rng=self.rng,
                               config=self.config, fit=fit)
        return held

    def select_on(self, sub, only=None) -> _Found:
        """Selection on the marks ``sub``, with joint harmonics no candidate offers found
        in the residual and fitted as nuisances (never reported as something else).
        ``only``: the labels of the candidates that may be added (else every candidate);
        the others still count as offered (a harmonic they model is no nuisance)."""
        cands, config = self.cands, self.config
        allowed = [c for c in cands if only is None or c.label in only]
        qs, xs, aps = self.q[sub], self.xy[sub], self.app[sub]
        ss = None if self.sigma is None else self.sigma[sub]
        idl = None if self.ids is None else tuple(np.asarray(self.ids, dtype=object)[sub])
        held = self.held_on(sub)
        b = _fit(self.base_model, qs, xs, aps, ss, idl, config).or_raise()
        sl = _select(b, (), allowed, qs, xs, aps, ss, idl, held, self.alpha_each,
                     self.max_effects, config)
        # harmonics significant even beside every candidate the plan can fit
        full = sl.fit
        for c in cands:
            if c.key in {k.key for k in cands if any(k.label == a.label for a in sl.accepted)}:
                continue
            f = _fit(full.model.with_effect(c.effect), qs, xs, aps, ss, idl, config)
            full = f or full
        fnd = _unexplained_harmonics(full, qs, aps, ss, cands, self.alpha, ids=idl, xy=xs,
                                     config=config)
        nui = tuple(JointCyclic(joint=h["joint"], harmonic=h["harmonic"]) for h in fnd)
        if nui:
            sl = _select(b, nui, allowed, qs, xs, aps, ss, idl, held, self.alpha_each,
                         self.max_effects, config)
        return _Found(sl, fnd, nui)


def _problem(q_deg, xy_mm, approach, *, sigma_mm, ids, q_val, xy_val, approach_val,
             candidates, alpha, k_folds, max_effects, rng, base_effects,
             config: EstimatorConfig) -> _Problem:
    """:func:`diagnose`'s arguments as arrays (joints (N, 2) or, with joint 4, (N, 3);
    approach all +1 when not given) and its levels (the arguments given, else
    ``config.selection``'s)."""
    sel_cfg = config.selection
    alpha = sel_cfg.alpha if alpha is None else alpha
    k_folds = sel_cfg.k_folds if k_folds is None else k_folds
    max_effects = sel_cfg.max_effects if max_effects is None else max_effects
    q = np.asarray(q_deg, dtype=float)
    ncol = 3 if q.ndim == 2 and q.shape[-1] == 3 else 2
    q = q.reshape(-1, ncol)
    xy = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
    app = np.ones_like(q) if approach is None else np.asarray(approach, float).reshape(-1, ncol)
    sigma = None if sigma_mm is None else np.asarray(sigma_mm, dtype=float)
    base_model = RobotModel(ScaraParams(1.0, 1.0), tuple(base_effects)) if base_effects else None
    if q_val is not None:
        q_val = np.asarray(q_val, float).reshape(-1, ncol)
        xy_val = np.asarray(xy_val, float).reshape(-1, 2)
        approach_val = (np.ones_like(q_val) if approach_val is None
                        else np.asarray(approach_val, float).reshape(-1, ncol))
    has_val = q_val is not None and len(q_val) >= 3
    cands = list(candidates if candidates is not None else default_candidates())
    return _Problem(q, xy, app, sigma, ids, q_val, xy_val, approach_val, has_val, cands, alpha,
                    alpha / max(len(cands), 1), k_folds, max_effects, rng, base_model,
                    len(base_effects), sel_cfg.min_sheet_marks, config)


def marks_away_from(xy, sheet_map: dict, place=None) -> tuple[np.ndarray, float]:
    """The marks a local structure found by the sheet map (:func:`sheet_scan`: its peak and
    neighbourhood size ``k``) does not touch: farther from the peak than 1.5 times its
    ``k``-th nearest mark, or with ``place`` (N,) ints (the repeats of one commanded pose
    share one: :func:`commanded_places`) its ``k``-th nearest place, as the map counts
    its neighbours. Returns (mask over ``xy``, that radius in mm)."""
    d = np.linalg.norm(np.asarray(xy, float) - np.asarray(sheet_map["peak_mm"]), axis=1)
    if place is not None:       # each place at its mark nearest the peak
        _, place = np.unique(place, return_inverse=True)
        near = np.full(place.max() + 1 if len(d) else 0, np.inf)
        np.minimum.at(near, place.reshape(-1), d)
    else:
        near = d
    radius = 1.5 * np.sort(near)[min(sheet_map["k"], len(near) - 1)]
    return d > radius, float(radius)


def commanded_places(q, app) -> np.ndarray:
    """The place of each mark (N,) ints: marks commanded to the same joints from the same
    sides (a pose's repeats) share one."""
    rows = np.column_stack([np.asarray(q, float), np.asarray(app, float)])
    return np.unique(rows, axis=0, return_inverse=True)[1].reshape(-1)


def enough_away(outside: np.ndarray) -> bool:
    """Whether the marks ``outside`` a local structure are enough to select on instead of
    every mark (12, and half of them)."""
    return bool(outside.sum() >= max(12, len(outside) // 2))


def local_map(xy, fit: Fit, min_marks: int) -> dict:
    """The sheet map (:func:`sheet_scan`) of ``fit``'s residual over the marks at ``xy``
    (N, 2) it was fitted to (its inliers; no test, p 1, below ``min_marks`` of them:
    config ``selection.min_sheet_marks``)."""
    keep = fit.inliers
    if keep.sum() < min_marks:
        return {"p_value": 1.0, "k": 0}
    return sheet_scan(np.asarray(xy, float)[keep], fit.residuals_mm[keep])


def _local_map(pb: _Problem, fit: Fit, sub) -> dict:
    """:func:`local_map` of ``fit``, fitted to the marks ``sub`` of the problem."""
    return local_map(pb.xy[sub], fit, pb.min_sheet_marks)


def _away_from_local(pb: _Problem, found: _Found, base: Fit) -> tuple[_Found, dict]:
    """The sheet map of the residual once the nuisance harmonics are out; when neighbouring
    marks share a residual (p below alpha / 2), the selection again without the marks
    there, so the local structure is not explained by a global effect (when enough marks
    are left), and the map as that model sees it. Returns (the selection, the map).

    The rule (a library effect is claimed only where nothing local explains it better):

    - the map is read after the selection and, when the selection added effects, before
      it (on the base model's residual): effects that took up a local structure leave no
      map after them (bench/discover_bump.py: a joint-1 backlash or scale claimed for a
      bump);
    - away from it, the map of the new residual is read again, and the marks where
      neighbours still share a residual are left out too, as long as enough are left
      (:func:`enough_away`);
    - an effect the selection away from it adds is kept only when every mark confirms it
      (:func:`_confirmed_on_every_mark`: significant and lowering the held-out error
      beside the others); one only the structure's tails asked for is rejected, and the
      selection runs again without it. When the map was seen only before the selection
      and both selections agree, the selection on every mark stands."""
    every = np.ones(len(pb.q), dtype=bool)
    sel = found.selection
    level = pb.alpha / 2
    after = sheet_map = _local_map(pb, sel.fit, every)
    before_only = False
    if sheet_map["p_value"] >= level and sel.accepted:
        seen = _local_map(pb, base, every)
        before_only = seen["p_value"] < level
        sheet_map = seen if before_only else sheet_map
    if sheet_map["p_value"] >= level:
        return found, sheet_map
    place = commanded_places(pb.q, pb.app)
    outside, radius = marks_away_from(pb.xy, sheet_map, place)
    if not enough_away(outside) and before_only:
        return found, after     # nothing to check it on: the selection's own map stands
    sheet_map["excluded_radius_mm"] = float(radius)
    sheet_map["excluded_marks"] = int((~outside).sum())
    if not enough_away(outside):
        return found, sheet_map
    away = pb.select_on(outside)
    while True:
        again = _local_map(pb, away.selection.fit, outside)
        if again["p_value"] >= level:
            break
        wider = outside.copy()
        wider[outside] = marks_away_from(pb.xy[outside], again, place[outside])[0]
        if not enough_away(wider):
            break
        outside, away = wider, pb.select_on(wider)
    if before_only and ([a.label for a in away.selection.accepted]
                        == [a.label for a in sel.accepted]):
        return found, after
    away = _confirmed_on_every_mark(pb, base, away, outside)
    sheet_map["excluded_radius_mm"] = float(radius)
    sheet_map["excluded_marks"] = int((~outside).sum())
    # the map as the model fitted away from the structure sees it
    again = sheet_scan(pb.xy, pb.xy - away.selection.fit.predict(pb.q, pb.app), n_perm=0)
    sheet_map.update({k: again[k] for k in ("peak_mm", "peak_size_mm",
                                            "peak_residual_mm", "map")})
    return away, sheet_map


def _unconfirmed(pb: _Problem, base: Fit, sel: "_Selection") -> list:
    """The effects ``sel`` added that, on every mark, beside the others it added, are not
    significant or do not lower the held-out error (:func:`_select`'s own test, one
    candidate): what only the marks away from a local structure (its tails) asked for."""
    every = np.ones(len(pb.q), dtype=bool)
    held = pb.held_on(every)
    by_label = {c.label: c for c in pb.cands}
    out = []
    for a in sel.accepted:
        model = base.model
        for b in sel.accepted:
            if b.label != a.label:
                model = model.with_effect(by_label[b.label].effect)
        start = _fit(model, pb.q, pb.xy, pb.app, pb.sigma, pb.ids, pb.config)
        if not start:
            continue        # the others cannot be fitted on every mark: nothing to test
        one = _select(start, (), [by_label[a.label]], pb.q, pb.xy, pb.app, pb.sigma, pb.ids,
                      held, pb.alpha_each, 1, pb.config)
        if not one.accepted:
            out.append(a)
    return out


def _confirmed_on_every_mark(pb: _Problem, base: Fit, away: _Found, outside) -> _Found:
    """The selection away from a local structure, without the effects every mark does not
    confirm (:func:`_unconfirmed`): it runs again without them, until each effect it adds
    is confirmed; the dropped ones are reported rejected, with the reason."""
    dropped = []
    while True:
        bad = _unconfirmed(pb, base, away.selection)
        if not bad:
            break
        dropped += bad
        gone = {a.label for a in dropped}
        away = pb.select_on(outside, only={c.label for c in pb.cands} - gone)
    away.selection.rejected.extend(
        replace(a, accepted=False, effect=None, reason="added away from a local structure, "
                "but on every mark not significant or not lowering the held-out error")
        for a in dropped)
    return away


@dataclass(frozen=True)
class _Reported:
    """The reported model's fit on every mark, its held-out RMS and the base model's."""

    fit: Fit
    held: float
    base_held: float


def _reported(pb: _Problem, base: Fit, found: _Found) -> _Reported:
    """The reported model: the selected effects only (a nuisance is reported, not fitted),
    on every mark; refitted from zero when the selection held nuisances or ran on fewer
    marks, else the selection's own fit and held-out figures."""
    sel, nuisance, n_base = found.selection, found.nuisance, pb.n_base
    effects = (sel.fit.model.effects[:n_base]
               + tuple(sel.fit.model.effects[n_base + len(nuisance):]))
    if nuisance or len(sel.fit.residuals_mm) != len(pb.q):
        zero = RobotModel(base.params, tuple(_at_zero(e) for e in effects))
        current = _fit(zero if effects else None, pb.q, pb.xy, pb.app, pb.sigma, pb.ids,
                       pb.config).or_raise()
        held = pb.held_on(np.ones(len(pb.q), dtype=bool))
        current_held = held(current.model, fit=current)
        return _Reported(current, current_held, held(base.model, fit=base))
    return _Reported(sel.fit, sel.held, sel.base_held)


def _final_analysis(pb: _Problem, current: Fit, sheet_map: dict) -> dict:
    """What the reported model's residual shows (:func:`residual_analysis`), its joint
    periodogram (weighted by 1 / sigma) and the sheet map."""
    analysis = residual_analysis(current, pb.q, pb.app)
    keep = current.inliers
    w = None if pb.sigma is None else 1.0 / np.asarray(pb.sigma)[keep]
    analysis["periodogram"] = harmonic_scan(current.model, pb.q[keep], pb.app[keep],
                                            current.residuals_mm[keep], weights=w)
    analysis["sheet_map"] = sheet_map
    return analysis


@dataclass
class _Selection:
    fit: Fit
    held: float
    base_held: float
    accepted: list
    rejected: list
    not_identifiable: list


def _at_zero(e):
    return e if isinstance(e, Tool) else e.with_theta(np.zeros(len(e.theta)))


class _SheetProblem(Problem):
    """One sheet's marks posed to the forward selection (:mod:`vision_cal.estimate.forward`):
    every parameter of the model free, the candidates' effects added one at a time
    (:func:`_fit`); the residual sum of squares of a fit's inliers weighted by ``1 /
    sigma``, the degrees of freedom from the base fit's inliers, the held-out error
    ``held``; a sheet scale along x or along y kept for the alternative whose printed scale
    shrinks, one below what the scale bars can be measured to never claimed; a candidate
    that cannot be fitted reported not identifiable with the plan change that fixes it."""

    def __init__(self, base: Fit, q, xy, app, sigma, ids, held, config: EstimatorConfig):
        self.q, self.xy, self.app, self.sigma, self.ids = q, xy, app, sigma, ids
        self.held_of, self.config = held, config
        self.n_obs = 2 * int(base.inliers.sum())
        self.not_ident: list[dict] = []

    def fit_with(self, current: Fit, c: Candidate):
        return _fit(current.model.with_effect(c.effect), self.q, self.xy, self.app,
                    self.sigma, self.ids, self.config)

    def rss(self, fit: Fit) -> float:
        return _rss_w(fit, self.sigma)

    def n_params(self, fit: Fit) -> int:
        return fit.n_params

    def dof(self, fit: Fit) -> int:
        return max(self.n_obs - fit.n_params, 1)

    def held(self, fit: Fit) -> float:
        return self.held_of(fit.model, fit=fit)

    def order(self, trials: list) -> list:
        return _prefer_shrink(trials)

    def too_small(self, t: Trial) -> bool:
        return _below_paper_floor(t.candidate, t.fit, self.config)

    def failed(self, c: Candidate, f) -> None:
        if not any(d["label"] == c.label for d in self.not_ident):
            self.not_ident.append({"label": c.label, "reason": f.reason, "fix": c.fix})

    def excludes(self, chosen: Candidate, c: Candidate) -> bool:
        return c.key == chosen.key      # alternatives (a sheet scale along x or y): one


def _select(base: Fit, nuisance: tuple, cands, q, xy, app, sigma, ids, held, alpha_each,
            max_effects, config: EstimatorConfig) -> _Selection:
    """Forward selection from the base model (plus ``nuisance`` effects, fitted but never
    reported: structure no candidate explains), by the estimator's one rule
    (:func:`vision_cal.estimate.forward.forward_select`) on this sheet's problem
    (:class:`_SheetProblem`); the accepted effects with their evidence, and the last
    round's rejected candidates with the reason each was not added."""
    if nuisance:
        current = _fit(RobotModel(base.params, base.model.effects + nuisance), q, xy, app,
                       sigma, ids, config).or_raise()
    else:
        current = base
    problem = _SheetProblem(base, q, xy, app, sigma, ids, held, config)
    # the selection's fits are of these marks, robust, as the held-out test's: reused
    rounds, fit, fit_held = forward_select(problem, current, cands, alpha_each=alpha_each,
                                           max_effects=max_effects)
    base_held = rounds[0].held if rounds else fit_held
    accepted, rejected = [], []
    for r in rounds:
        if r.chosen is not None:
            t, h = r.chosen
            accepted.append(Evidence(t.candidate.label, r.held, h, t.rss0, t.rss1, t.F, t.p,
                                     t.dbic, True, "significant and lowers the held-out error",
                                     t.fit.model.effects[-1].to_json()))
            continue
        for t in r.trials:              # the last round: why each was not added
            h = r.held_of(t)
            why = ("not significant" if t.p >= alpha_each or t.dbic >= 0 else
                   f"smaller than the {config.selection.min_sheet_affine:.2%} the printed "
                   "scale bars can be measured to" if problem.too_small(t) else
                   "held-out error not lowered" if not (h < r.held) else
                   "another candidate explains more")
            rejected.append(Evidence(t.candidate.label, r.held, h, t.rss0, t.rss1, t.F, t.p,
                                     t.dbic, False, why))
    return _Selection(fit, fit_held, base_held, accepted, rejected, problem.not_ident)


def _unexplained_harmonics(fit: Fit, q, app, sigma, cands, alpha, *, ids=None, xy=None,
                           max_found: int = 3, config: EstimatorConfig) -> list[dict]:
    """Joint harmonics significant in the residual that no candidate offers, at level
    ``alpha`` split over every harmonic scanned. One at a time, strongest first: each found
    one is fitted before the next scan (a strong harmonic of one joint leaks into the
    other joint's periodogram)."""
    offered = {(c.effect.joint, c.effect.harmonic) for c in cands
               if isinstance(c.effect, JointCyclic)}
    out = []
    if 2 * int(fit.inliers.sum()) - fit.n_params - 2 < config.selection.min_scan_dof:
        return out          # too few marks to tell a harmonic from the noise
    for _ in range(max_found):
        keep = fit.inliers
        w = None if sigma is None else 1.0 / np.asarray(sigma)[keep]
        scan = harmonic_scan(fit.model, q[keep], app[keep], fit.residuals_mm[keep], weights=w)
        n_tests = sum(len(v) for v in scan.values())
        sig = [dict(r, joint=int(name[-1])) for name, rows in scan.items() for r in rows
               if r["p_value"] < alpha / n_tests
               and (int(name[-1]), r["harmonic"]) not in offered
               and not any(o["joint"] == int(name[-1]) and o["harmonic"] == r["harmonic"]
                           for o in out)]
        if not sig:
            break
        best = max(sig, key=lambda r: r["F"])
        out.append(best)
        fit = _fit(fit.model.with_effect(JointCyclic(joint=best["joint"],
                                                     harmonic=best["harmonic"])),
                   q, xy, app, sigma, ids, config)
        if not fit:
            break
    return out


def _rss_w(fit: Fit, sigma) -> float:
    r = fit.residuals_mm[fit.inliers]
    if sigma is not None:
        r = r / np.asarray(sigma)[fit.inliers, None]
    return float(np.sum(r**2))


def _below_paper_floor(c: Candidate, f: Fit, config: EstimatorConfig) -> bool:
    """A paper-scale effect (``sheet_affine``) smaller than the sheet's scale bars can be
    measured to (config ``selection.min_sheet_affine``): a claim nobody could check on
    the paper, and the size a slightly tilted camera or motion plane leaves."""
    if not isinstance(c.effect, SheetAffine):
        return False
    theta = f.model.effects[-1].theta
    return bool(len(theta)) and float(np.max(np.abs(theta))) < config.selection.min_sheet_affine


def _prefer_shrink(trials: list) -> list:
    """A sheet scale along x or along y: the same fit (one is the other with the lengths
    scaled); the sheet shrinks, so the alternative whose printed scale is above one stays."""
    sheet = [t for t in trials if isinstance(t.candidate.effect, SheetAffine)
             and t.candidate.effect.dof in "xy"]
    if len(sheet) == 2:
        a, b = sheet
        if abs(a.rss1 - b.rss1) <= 0.05 * max(a.rss1, b.rss1):
            drop = a if a.fit.model.effects[-1].theta[0] < 0 else b
            trials = [t for t in trials if t is not drop]
    return trials


def _unexplained(analysis: dict, alpha: float, harmonics=(), sheet_alpha=None) -> dict | None:
    """What the final model leaves that no candidate explains: joint harmonics outside the
    candidates (joint, harmonic, amplitude, the joint's periodogram), residuals shared by
    neighbouring marks (where on the sheet, how big, the map), and the binned checks."""
    seen, out = [], {}
    for h in harmonics:
        seen.append(f"joint{h['joint']} residual has a harmonic {h['harmonic']} of "
                    f"{h['amplitude_deg']:.4f} deg (F = {h['F']:.1f}, p = {h['p_value']:.2g}), "
                    f"which no candidate models")
    if harmonics:
        out["joint_harmonics"] = [dict(h, periodogram=analysis["periodogram"][
            f"joint{h['joint']}"]) for h in harmonics]
    sm = analysis.get("sheet_map")
    if sm and sm.get("p_value", 1.0) < (alpha / 2 if sheet_alpha is None else sheet_alpha):
        seen.append(f"neighbouring marks share their residual (p = {sm['p_value']:.2g}): "
                    f"largest {sm['peak_size_mm']:.3f} mm near "
                    f"({sm['peak_mm'][0]:.0f}, {sm['peak_mm'][1]:.0f}) mm on the sheet")
        out["sheet"] = sm
    for j in ("joint1", "joint2"):
        res = analysis.get(j, {})
        ba = res.get("by_approach_deg")
        if ba and ba["p_value"] < alpha / 10:
            seen.append(f"{j} residual depends on the approach direction "
                        f"({ba['+1']:+.4f} vs {ba['-1']:+.4f} deg, p = {ba['p_value']:.2g})")
        bn = res.get("by_angle")
        if bn and bn["p_value"] < alpha / 10:
            seen.append(f"{j} residual varies with the joint angle (chi2 = {bn['chi2']:.1f}, "
                        f"p = {bn['p_value']:.2g})")
    return {"seen": seen, **out} if seen else None
