"""The run's judgement of itself: the noise-floor gate and the contract's ``verdict`` block.

One owner. :func:`judge` reads a calibration document (calibration.json as a dict) and
returns the :class:`Verdict` that calibration.json carries as ``verdict`` (status,
``expected_target_error_mm``, ``residual_over_floor``, ``reasons``; docs/format.md); the
console, the report and other programs read that block and decide nothing themselves.
:func:`judge_camera_poses` is the same judgement for a calibration from the arm camera's
photos (``vision-cal handeye``), each photo's flange position standing for a mark.

The noise floor. Each mark's position carries the measurer's per-axis standard deviation
``sigma_mm`` (calibration.json ``marks[].sigma_mm``); the robot adds its repeatability
``r`` (one standard deviation per axis, the synthetic world's meaning too): measured from
marks drawn twice at the same command when at least ``verdict.min_repeat_pairs`` pairs
resolve it from the measurement noise (an unbiased estimate with its std,
:func:`repeatability_from_repeats`), else the robot block's ``repeatability_mm``, else
``verdict.default_repeatability_mm`` (the pairs' upper bound said beside it); never 0 for
want of evidence. If the model is right, the fitted residuals are that noise alone::

    chi2 = sum_i |res_i|^2 / (sigma_i^2 + r^2)     over the fitted marks (outliers out)
    dof  = 2 N - P                                  (P fitted parameters)

is chi-square with ``dof`` degrees of freedom; ``residual_over_floor = sqrt(chi2 / dof)``
(1 where noise explains it all) and its p-value is ``chi2.sf(chi2, dof)`` (a floor the
pairs measured has its own ``2 n`` degrees of freedom: the F distribution's then). The gate is
passed unless the p-value is below ``verdict.floor_alpha`` *and* the ratio above
``verdict.floor_ratio_tol`` (a ratio that small is within how well a measurer knows its own
noise). Held-out marks are judged against the same floor, their variance raised by the
model's own prediction error, on average ``P / (2 N)`` of the noise (the mean leverage).

The largest target error. An RMS can hide one target far off (a local error: a fold in the
paper, a bad mark, a pose the model misses). The largest error over the held-out marks
(the fitted marks when none are held out) is judged against the same noise: each mark's
``t = |r|^2 / var`` is chi-square with 2 dof, so the largest of N exceeds ``t_max`` by noise
alone with probability ``1 - (1 - exp(-t_max / 2))^N``, computed with the variance raised
by ``floor_ratio_tol^2`` (the noise is known only that well); below ``floor_alpha``
it is a reason (``check``), and ``max_target_error`` is in the block either way.

Status: ``not reliable`` when the plan cannot identify the model, the robot drifted, or the
residual is beyond the floor by ``verdict.not_reliable_ratio`` or more; ``check`` for every
other reason listed (beyond the floor by less, a target error beyond the noise, structure
left - an ``unexplained`` effect, photos whose marks moved together, a printed grid that
disagrees with the markers the way a lens error does - the scans for unnamed effects not
run, outliers or unreliable marks, too few marks, no noise known); ``ready`` only with no
reason at all.

The expected target error (``expected_target_error_mm``, the 95 % radius) is that of a
target's error whose per-axis std holds the calibration's covariance, the repeatability,
what the model leaves beyond the noise and the print (``target_std``; without the marks'
noise, the held-out RMS with the print); the print not measured (no survey, photos from
fewer than three camera places, a fixed camera) is ``check`` with a printer's deviation
in it. ``ready`` also needs the fit's two halves to agree within what each states
(calibration.json ``replication``, :mod:`vision_cal.estimate.replicate`).

The thresholds are calibration.json ``config.verdict`` (:class:`vision_cal.config.VerdictConfig`)
and ``config.uncertainty``:
:func:`judge` reads the ones the document recorded (the defaults for a file without them),
so a calibration judged again is judged by its own rules.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import stats

from vision_cal.config import DEFAULT, EstimatorConfig, VerdictConfig
from vision_cal.dataset.calibration_result import CalibrationResult, ModelRms
from vision_cal.dataset.valid_for import verdict_reasons as valid_for_reasons
from vision_cal.measure.print_stage import print_not_measured, unmeasured_print_size

#: radius holding 95 % of a circular normal 2-D error per unit of its RMS
R95_PER_RMS = math.sqrt(-2.0 * math.log(0.05)) / math.sqrt(2.0)
#: radius holding 95 % of a circular normal 2-D error per unit of its per-axis std
R95_PER_STD = math.sqrt(-2.0 * math.log(0.05))

_RANK = {"ready": 0, "check": 1, "not reliable": 2}


@dataclass(frozen=True)
class FloorTest:
    """The residual of some marks against the noise floor."""

    n_marks: int
    dof: int
    chi2: float
    p_value: float
    ratio: float            # sqrt(chi2 / dof): residual over floor
    rms_mm: float           # 2-D RMS of the residuals
    floor_rms_mm: float     # 2-D RMS the noise alone gives
    beyond: bool            # p below the gate's level and the ratio above its tolerance

    def to_json(self) -> dict:
        return {"n_marks": self.n_marks, "dof": self.dof, "chi2": self.chi2,
                "p_value": self.p_value, "residual_over_floor": self.ratio,
                "rms_mm": self.rms_mm, "floor_rms_mm": self.floor_rms_mm,
                "beyond": self.beyond}


def floor_test(residual_mm, sigma_mm, repeatability_mm: float | None = None, *,
               n_params: int = 0, inflate: float = 1.0,
               config: VerdictConfig | None = None,
               floor_dof: int | None = None) -> FloorTest | None:
    """Chi-square of residuals (N, 2) against per-mark per-axis noise ``sigma_mm`` (N,)
    plus ``repeatability_mm`` (None: ``config.default_repeatability_mm``); ``n_params``
    fitted parameters (0 for held-out marks); ``inflate`` multiplies the variance (held-out
    marks: 1 + P / 2N); ``config`` the gate's thresholds. ``floor_dof``: the degrees of
    freedom the floor itself was measured with (marks drawn twice: 2 a pair), its p-value
    then the F distribution's of ``chi2 / dof`` (a floor 8 pairs measured is known within
    35 % in variance, which a chi-square would read as a missing effect); None: the floor
    is taken as known. None if no dof."""
    config = config or DEFAULT.verdict
    if repeatability_mm is None:
        repeatability_mm = config.default_repeatability_mm
    r = np.asarray(residual_mm, dtype=float).reshape(-1, 2)
    s = np.asarray(sigma_mm, dtype=float).reshape(-1)
    var = (s**2 + float(repeatability_mm) ** 2) * inflate
    ok = np.all(np.isfinite(r), axis=1) & np.isfinite(var) & (var > 0)
    n = int(ok.sum())
    dof = 2 * n - int(n_params)
    if dof <= 0:
        return None
    chi2 = float(np.sum(r[ok] ** 2 / var[ok, None]))
    p = float(stats.chi2.sf(chi2, dof) if not floor_dof else
              stats.f.sf(chi2 / dof, dof, floor_dof))
    ratio = math.sqrt(chi2 / dof)
    return FloorTest(n, dof, chi2, p, ratio,
                     float(np.sqrt(np.mean(np.sum(r[ok] ** 2, axis=1)))),
                     float(np.sqrt(2 * np.mean(var[ok]) * dof / (2 * n))),
                     bool(p < config.floor_alpha and ratio > config.floor_ratio_tol))


@dataclass(frozen=True)
class MaxErrorTest:
    """The largest error of some marks against the noise (module docstring)."""

    mark: str
    error_mm: float         # |r| of the worst mark
    over_noise: float       # |r| / sqrt(2 var): its error over its own 2-D noise RMS
    p_value: float          # the largest of n noise-only errors this large (tolerant)
    n_marks: int
    of: str                 # held-out | fitted
    beyond: bool            # p below the gate's level

    def to_json(self) -> dict:
        return {"mark": self.mark, "error_mm": self.error_mm, "over_noise": self.over_noise,
                "p_value": self.p_value, "n_marks": self.n_marks, "of": self.of,
                "beyond": self.beyond}


def max_error_test(ids, residual_mm, sigma_mm, repeatability_mm: float, *, of: str,
                   inflate: float = 1.0,
                   config: VerdictConfig | None = None) -> MaxErrorTest | None:
    """The largest of the residuals (N, 2) of marks ``ids`` against their per-axis noise
    ``sigma_mm`` (N,) plus ``repeatability_mm`` (variance times ``inflate``); ``config``
    the gate's thresholds. None: no mark."""
    config = config or DEFAULT.verdict
    r = np.asarray(residual_mm, dtype=float).reshape(-1, 2)
    var = (np.asarray(sigma_mm, dtype=float).reshape(-1) ** 2 + repeatability_mm**2) * inflate
    ok = np.all(np.isfinite(r), axis=1) & np.isfinite(var) & (var > 0)
    if not ok.any():
        return None
    t = np.where(ok, np.sum(r**2, axis=1) / np.where(ok, var, 1.0), -np.inf)
    k = int(np.argmax(t))
    n = int(ok.sum())
    # P(max of n chi2(2) >= t): 1 - (1 - e^{-t/2})^n, in a form exact for tiny tails
    tail = -np.expm1(n * np.log1p(-math.exp(-t[k] / (2 * config.floor_ratio_tol**2))))
    return MaxErrorTest(str(ids[k]), float(np.hypot(*r[k])), float(math.sqrt(t[k] / 2)),
                        float(tail), n, of, bool(tail < config.floor_alpha))


@dataclass(frozen=True)
class Repeatability:
    """The robot's repeatability the floor and the targets' std use (mm, per axis, one
    std), where it comes from (``source``: ``default``, ``robot block`` or ``N pairs of
    marks drawn at the same command``) and what the marks drawn twice said of it
    (:func:`repeatability_from_repeats`): ``n_pairs``, their unbiased estimate of ``r^2``
    (mm^2, may be below 0) and its std, ``measured`` when that estimate resolves it,
    ``std_mm`` then its one std; ``prior_mm`` the figure used when it does not; ``why`` one
    sentence."""

    mm: float
    source: str
    n_pairs: int = 0
    r2_mm2: float | None = None
    r2_std_mm2: float | None = None
    measured: bool = False
    prior_mm: float | None = None
    why: str = ""

    @property
    def floor_dof(self) -> int | None:
        """The degrees of freedom of the floor when the pairs gave the figure (2 a pair:
        their differences measure ``sigma^2 + r^2`` itself), else None (a prior, taken as
        known)."""
        return 2 * self.n_pairs if self.source.endswith("drawn at the same command") else None

    @property
    def std_mm(self) -> float | None:
        """One std of :attr:`mm` when the pairs measured it (``r2_std / 2 r``), else None."""
        if not self.measured or not self.mm > 0 or self.r2_std_mm2 is None:
            return None
        return self.r2_std_mm2 / (2 * self.mm)

    def to_json(self) -> dict:
        return {"mm": self.mm, "source": self.source, "n_pairs": self.n_pairs,
                "r2_mm2": self.r2_mm2, "r2_std_mm2": self.r2_std_mm2,
                "measured": self.measured, "std_mm": self.std_mm, "prior_mm": self.prior_mm,
                "why": self.why}


def repeat_pair_terms(marks: dict) -> list[float]:
    """Each pair of marks drawn at the same command: ``|d|^2 / 4 - (sigma_a^2 + sigma_b^2) /
    2`` (mm^2), an unbiased estimate of the robot's ``r^2`` (per axis) when each mark's
    ``sigma_mm`` is its measurement noise.

    A pair is a mark and the one its ``repeat_of`` names (the design returns to a pose a
    few millimetres off, ``plan.calibration_plan.add_repeats``: their residuals differ by
    noise alone, the model taking the offset out), or two marks of the same command and
    approach (their measured positions). Two marks a, b differ per axis by noise of
    variance ``sigma_a^2 + sigma_b^2 + 2 r^2``: ``E |d|^2 = 2 (sigma_a^2 + sigma_b^2) +
    4 r^2`` over the two axes."""
    def usable(m) -> bool:
        return (m.get("status", "ok") == "ok" and m.get("sigma_mm") is not None
                and m.get("joints_deg") is not None)

    pairs = []
    for k, m in marks.items():
        twin = marks.get(m.get("repeat_of") or "")
        if twin is not None and usable(m) and usable(twin) \
                and m.get("residual_mm") is not None and twin.get("residual_mm") is not None:
            pairs.append((m, twin, "residual_mm"))
    groups: dict = {}
    for k, m in marks.items():
        if not usable(m) or m.get("measured_mm") is None or m.get("repeat_of"):
            continue
        key = (tuple(np.round(m["joints_deg"], 6)), tuple(m.get("approach") or (1, 1)))
        groups.setdefault(key, []).append(m)
    for ms in groups.values():
        pairs += [(a, b, "measured_mm") for a, b in zip(ms[:-1], ms[1:])]
    out = []
    for a, b, field in pairs:
        d = np.subtract(a[field], b[field])
        out.append(float(d @ d) / 4 - (a["sigma_mm"] ** 2 + b["sigma_mm"] ** 2) / 2)
    return out


def repeatability_from_repeats(marks: dict, config: EstimatorConfig | None = None, *,
                               prior_mm: float | None = None,
                               prior_source: str = "robot block") -> Repeatability:
    """The robot's repeatability from marks drawn twice (:func:`repeat_pair_terms`), never
    biased to 0 and never 0 for want of evidence.

    The pairs' terms ``t_i`` average to an unbiased ``r^2`` (it may come out below 0:
    noise, or a measurement noise stated too large), with the std ``std(t) / sqrt(n)``.
    With at least ``verdict.min_repeat_pairs`` pairs and the estimate above
    ``uncertainty.repeat_resolve_sigmas`` of its std, it is the repeatability (``measured``;
    its std ``std(r^2) / 2 r``: 8 pairs give the floor's variance within about 35 %,
    inside the gate's tolerance of 1.25^2). Otherwise the pairs do not resolve it from the measurement noise,
    and the prior is used (``prior_mm``, the robot block's, named ``prior_source``; else
    ``verdict.default_repeatability_mm``, a catalogue's figure), the pairs' upper bound
    (``r^2 + resolve_sigmas std``) said beside it, unless the pairs' estimate is above the
    prior (then it: the pairs say at least that much; a robot of 0.016 mm under a default
    of 0.01 read 1.36 times its floor). A clip at 0 read a robot of 0.01 mm as
    0.0 mm where the measurement's stated noise exceeded its real one (the README's
    rehearsal: ``sigma_mm`` 0.0104 mm against 0.0070 mm of real error, 8 pairs); a cap
    at the upper bound, whose std comes from 8 terms, fell below the true figure there
    one time in ten."""
    cfg = config or DEFAULT
    vc, uc = cfg.verdict, cfg.uncertainty
    # a robot block's 0 is no robot's repeatability: the default then (never 0)
    prior, psrc = ((float(prior_mm), prior_source) if prior_mm is not None and prior_mm > 0
                   else (vc.default_repeatability_mm, "default"))
    t = np.asarray(repeat_pair_terms(marks), float)
    n = len(t)
    if n < vc.min_repeat_pairs:
        why = (f"{n} pair(s) of marks drawn at the same command, {vc.min_repeat_pairs} needed "
               f"to measure it: the {_prior_name(psrc)} {prior:.4f} mm")
        return Repeatability(prior, psrc, n, prior_mm=prior, why=why)
    r2 = float(np.mean(t))
    sd = float(np.std(t, ddof=1) / math.sqrt(n))
    said = f"{n} pairs of marks drawn at the same command"
    if r2 > uc.repeat_resolve_sigmas * sd:
        r = math.sqrt(r2)
        return Repeatability(r, said, n, r2, sd, True, prior,
                             f"{said}: {r:.4f} +- {sd / (2 * r):.4f} mm")
    upper = math.sqrt(max(r2, 0.0) + uc.repeat_resolve_sigmas * sd)
    if r2 > prior**2:   # not resolved from 0, but more than the prior: the pairs' figure
        return Repeatability(math.sqrt(r2), said, n, r2, sd, False, prior,
                             f"{said} give r^2 = {r2:.2e} +- {sd:.1e} mm^2, not resolved "
                             f"from the measurement noise but above the {_prior_name(psrc)} "
                             f"{prior:.4f} mm: {math.sqrt(r2):.4f} mm")
    return Repeatability(prior, psrc, n, r2, sd, False, prior,
                         f"{said} give r^2 = {r2:.2e} +- {sd:.1e} mm^2 (r at most {upper:.4f} "
                         f"mm), not resolved from the measurement noise: the "
                         f"{_prior_name(psrc)} {prior:.4f} mm")


def _prior_name(source: str) -> str:
    return {"default": "default (config verdict.default_repeatability_mm)",
            "robot block": "robot block's"}.get(source, source)


@dataclass(frozen=True)
class Verdict:
    """The contract's ``verdict`` block plus the gate's figures (added fields)."""

    status: str                          # ready | check | not reliable
    expected_target_error_mm: float | None
    residual_over_floor: float | None
    reasons: tuple[str, ...]
    floor: dict | None = None            # FloorTest.to_json of the fitted marks
    heldout_floor: dict | None = None    # FloorTest.to_json of the validation marks
    repeatability_mm: float | None = None   # None: not said (an old block)
    repeatability_source: str = "default"
    max_target_error: dict | None = None  # MaxErrorTest.to_json
    #: the status inside calibration.json ``valid_for`` when what it could not identify
    #: holds it back (None: nothing does)
    within_valid_for: str | None = None
    #: one kind per reason, in the same order (``reason_codes`` in docs/format.md; () in an
    #: old block),
    #: and the status each reason gives on its own (``ready`` for what a pilot leaves to
    #: the informative plan by design)
    reason_codes: tuple[str, ...] = ()
    reason_levels: tuple[str, ...] = ()
    #: :class:`Repeatability` as JSON (what the marks drawn twice said; None: not judged)
    repeatability: dict | None = None
    #: a target's error by part, one std per axis (``_target_parts``; None: noise unknown)
    target_std: dict | None = None

    @property
    def text(self) -> str:
        """The one-line judgement the console and the report print."""
        head = {"ready": "ready to use", "check": "check before use",
                "not reliable": "not reliable"}[self.status]
        e = self.expected_target_error_mm
        fig = f"expected target error {e:.3f} mm (95 %)" if e is not None else ""
        parts = [p for p in ([fig] if self.status == "ready" else
                             list(self.reasons) + ([fig] if fig else [])) if p]
        return head + (": " + "; ".join(parts) if parts else "")

    @property
    def floor_line(self) -> str | None:
        """One console line: the final residual against the noise floor."""
        f = self.floor
        if not f:
            return None
        tail = ("beyond the noise floor: the model misses something" if f["beyond"] else
                "within the noise floor")
        return (f"residual vs noise floor: {f['rms_mm']:.4f} mm vs {f['floor_rms_mm']:.4f} mm "
                f"({f['residual_over_floor']:.2f}x, chi2 = {f['chi2']:.1f} on {f['dof']} dof, "
                f"p = {f['p_value']:.2g}): {tail}")

    @classmethod
    def from_json(cls, d: dict) -> "Verdict":
        """Back from calibration.json's ``verdict`` block (what readers print)."""
        return cls(d["status"], d.get("expected_target_error_mm"), d.get("residual_over_floor"),
                   tuple(d.get("reasons") or ()), d.get("floor"), d.get("heldout_floor"),
                   d.get("repeatability_mm"),
                   d.get("repeatability_source", "default"), d.get("max_target_error"),
                   d.get("within_valid_for"), tuple(d.get("reason_codes") or ()),
                   tuple(d.get("reason_levels") or ()), d.get("repeatability"),
                   d.get("target_std"))

    def to_json(self) -> dict:
        d = {"status": self.status, "expected_target_error_mm": self.expected_target_error_mm,
             "residual_over_floor": self.residual_over_floor, "reasons": list(self.reasons),
             "repeatability_mm": self.repeatability_mm,
             "repeatability_source": self.repeatability_source}
        if self.floor is not None:
            d["floor"] = self.floor
        if self.heldout_floor is not None:
            d["heldout_floor"] = self.heldout_floor
        if self.max_target_error is not None:
            d["max_target_error"] = self.max_target_error
        if self.within_valid_for is not None:
            d["within_valid_for"] = self.within_valid_for
        if self.reason_codes:
            d["reason_codes"] = list(self.reason_codes)
            d["reason_levels"] = list(self.reason_levels)
        if self.repeatability is not None:
            d["repeatability"] = self.repeatability
        if self.target_std is not None:
            d["target_std"] = self.target_std
        return d


def _floor_reasons(floor: FloorTest | None, hfloor: FloorTest | None,
                   config: VerdictConfig) -> list[tuple[str, str]]:
    """(status, sentence) for a fitted and a held-out residual beyond the noise floor."""
    out = []
    for name, f in (("final residual", floor), ("held-out residual", hfloor)):
        if f is not None and f.beyond:
            out.append(("not reliable" if f.ratio >= config.not_reliable_ratio else "check",
                        f"the {name} is {f.ratio:.1f} times the noise floor ({f.rms_mm:.4f} vs "
                        f"{f.floor_rms_mm:.4f} mm, chi2 = {f.chi2:.0f} on {f.dof} dof, "
                        f"p = {f.p_value:.2g}): the model misses something"))
    return out


def _max_error_reasons(worst: MaxErrorTest | None, item: str,
                       hint: str) -> list[tuple[str, str]]:
    """(status, sentence) for the largest target error beyond the noise (module docstring);
    ``item`` names what was measured (a mark, a photo), ``hint`` what to look at."""
    if worst is None or not worst.beyond:
        return []
    return [("check", f"the largest {worst.of} target error, {worst.error_mm:.4f} mm at "
                      f"{item} {worst.mark}, is {worst.over_noise:.1f} times its noise (p = "
                      f"{worst.p_value:.2g} for the largest of {worst.n_marks}): a local error "
                      f"the RMS hides; {hint}")]


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _final(rms: ModelRms | None) -> float | None:
    """The final model's RMS of a ``residual_rms_mm`` / ``validation_rms_mm`` block."""
    return None if rms is None else rms.final_model


def judge(cal, *, repeatability_mm: float | None = None,
          stage: str | None = None) -> Verdict:
    """The verdict of a calibration (see the module docstring): its
    :class:`~vision_cal.dataset.calibration_result.CalibrationResult`, or a document (read
    into one). ``stage``: the
    design stage of the session (session.json ``design.stage``). A ``pilot`` is a rough
    model for designing the informative plan: what its nine marks cannot do by design
    (test effects, compare marks given as ``measured_mm`` with a noise floor) is said among
    the reasons at the ``ready`` level, so it does not hold the pilot back; the informative
    plan tests the effects. The thresholds: the document's own ``config.verdict``.

    The reasons are gathered stage by stage, in the order the verdict lists them within a
    status: the plan (:func:`_plan_reasons`), a drift, the noise floor
    (:func:`_noise_floor`), structure left (:func:`_structure_reasons`), marks left out,
    the accuracy figure (:func:`_accuracy`)."""
    if not isinstance(cal, CalibrationResult):
        cal = CalibrationResult.from_json(cal)
    full = EstimatorConfig.from_json(cal.config)
    cfg = full.verdict
    pilot = stage == "pilot"
    by_design = "ready" if pilot else None
    outliers = set(cal.outliers or [])
    marks = cal.marks or {}
    rp = repeatability_from_repeats({k: m for k, m in marks.items() if k not in outliers},
                                    full, prior_mm=repeatability_mm)
    rep, source = rp.mm, rp.source
    ident = cal.identifiability or {}
    n_par = int(ident.get("n_params") or 6)
    vf = cal.valid_for if isinstance(cal.valid_for, dict) else None
    reasons, outside = _plan_reasons(ident, vf, pilot)
    # each reason's kind (reason_codes): by the stage that found it
    outside = _coded(outside, "not_identified")
    reasons = _coded(reasons[:len(reasons) - len(outside)], "plan") + outside
    effects = list(cal.effects or [])
    reasons += _coded(_drift_reasons(effects), "drift")
    floors = _noise_floor(marks, outliers, n_par, rep, cfg, by_design, rp.floor_dof)
    reasons += _coded(floors.reasons, "noise_floor")
    reasons += _coded(_structure_reasons(cal, effects, marks), "structure")
    reasons += _coded(_left_out_reasons(outliers, marks), "left_out")
    reasons += _coded(_replication_reasons(cal.extra.get("replication"), by_design),
                      "replication")
    acc = _accuracy(cal, marks, n_par, rep, full, by_design)
    reasons += _coded(acc.reasons, "accuracy")
    v = _verdict(reasons, acc.r95, floors.floor, floors.hfloor, rep, source, floors.worst)
    if outside:   # the status inside valid_for (design --pilot accepts a pilot "ready" there)
        inner = _verdict([r for r in reasons if r not in outside], acc.r95, floors.floor,
                         floors.hfloor, rep, source, floors.worst)
        v = replace(v, within_valid_for=inner.status)
    return replace(v, repeatability=rp.to_json(), target_std=acc.parts)


def _replication_reasons(rep: dict | None, by_design: str | None) -> list[tuple[str, str]]:
    """(status, sentence) from calibration.json ``replication``
    (:mod:`vision_cal.estimate.replicate`): two halves of the marks that disagree beyond
    what each states (``check``: the stated std understates what the halves see), or a fit
    that could not be replicated (``check``; a pilot's at the ``ready`` level: its nine
    marks cannot be halved by design). Nothing for a file without the block (written
    before it, or by the paper's method)."""
    if not isinstance(rep, dict):
        return []
    if rep.get("agree") is None:
        return [(by_design or "check", "the fit could not be replicated by two halves of "
                                       f"the marks: {rep.get('reason') or 'no halves'}")]
    if rep["agree"]:
        return []
    worst = max((rep.get(k) or {} for k in ("params", "positions")),
                key=lambda b: b.get("chi2_dof") or 0.0)
    return [("check", f"two halves of the marks ({rep.get('split', 'two halves')}) disagree "
                      f"beyond the std each states (chi2/dof {worst.get('chi2_dof', 0):.1f} on "
                      f"{worst.get('dof', 0)} dof, p = {worst.get('p', 0):.2g}): the model or "
                      "the noise differs between them, and the stated std understates it")]


def _plan_reasons(ident: dict, vf: dict | None,
                  pilot: bool) -> tuple[list[tuple[str, str]], list[tuple[str, str]]]:
    """(status, sentence) for what the plan cannot identify: a rank below the parameters
    (``not reliable``), the first candidate it cannot separate from the base model (``not
    reliable``; a pilot's at the ``ready`` level, and not those ``valid_for`` says), and
    what ``valid_for`` says a user's targets would excite that the calibration could not
    identify (never ``ready``: dataset/valid_for). Returns (every reason, in that order;
    the ``valid_for`` ones among them)."""
    out: list[tuple[str, str]] = []
    if ident and ident.get("rank") is not None and ident["rank"] < ident.get("n_params", 0):
        out.append(("not reliable", f"the plan identifies only {ident['rank']} of "
                                    f"{ident['n_params']} parameters; add marks that spread "
                                    "both joints and both approach directions"))
    ni = ident.get("not_identifiable") or []
    vf_labels = {d.get("label") for d in (vf or {}).get("not_identified") or []}
    if pilot:   # said once, by valid_for below, at its own level (check, never ready)
        ni = [d for d in ni if d.get("label") not in vf_labels]
    if ni:
        d = ni[0]
        more = (" (nor " + ", ".join(str(e.get("label")) for e in ni[1:]) + ")"
                if len(ni) > 1 else "")
        out.append(("ready" if pilot else "not reliable",
                    f"the plan cannot separate {d['label']} from the base model{more}; "
                    f"{d['fix']}" + ("; a pilot leaves that to the informative plan"
                                     if pilot else "")))
    # what the calibration could not identify and a user's targets excite: never "ready"
    # (dataset/valid_for: plan and the other consumers refuse requests outside it)
    outside = valid_for_reasons(vf, skip_labels={d.get("label") for d in ni})
    return out + outside, outside


def _drift_reasons(effects: list) -> list[tuple[str, str]]:
    """``not reliable`` for each ``drift`` effect: the robot changed while it drew."""
    return [("not reliable", f"the robot changed while drawing ({e.get('size_mm', 0):.3f} mm "
                             f"from the first to the last mark, {e.get('along', '?')}): "
                             "warm it up / re-home, then draw again")
            for e in effects if e.get("name") == "drift"]


@dataclass(frozen=True)
class _Floors:
    """The document's marks against the noise floor: the fitted marks' and the held-out
    marks' floor tests, the largest target error (held-out marks' when judged, else the
    fitted marks'), and the (status, sentence) reasons they give."""

    floor: FloorTest | None
    hfloor: FloorTest | None
    worst: MaxErrorTest | None
    reasons: list[tuple[str, str]]


def _noise_floor(marks: dict, outliers: set, n_par: int, rep: float, cfg: VerdictConfig,
                 by_design: str | None, floor_dof: int | None = None) -> _Floors:
    """The floor tests of the fitted calibration marks (outliers out) and of the validation
    marks when every one carries its noise (``floor_dof``: the floor's own degrees of
    freedom when marks drawn twice measured it, :func:`floor_test`); without noise, a
    reason (``check``, or ``by_design``'s level for a pilot) saying the residual cannot be
    compared."""
    fitted_ids = [k for k, m in marks.items() if m.get("role", "calibration") == "calibration"
                  and k not in outliers and m.get("status", "ok") == "ok"]
    held_ids = [k for k, m in marks.items() if m.get("role") == "validation"
                and m.get("status", "ok") == "ok"]
    fitted = [marks[k] for k in fitted_ids]
    held = [marks[k] for k in held_ids]
    floor = hfloor = worst = None
    reasons: list[tuple[str, str]] = []
    if fitted and all(m.get("sigma_mm") is not None for m in fitted):
        floor = floor_test([m["residual_mm"] for m in fitted],
                           [m["sigma_mm"] for m in fitted], rep, n_params=n_par, config=cfg,
                           floor_dof=floor_dof)
        worst = max_error_test(fitted_ids, [m["residual_mm"] for m in fitted],
                               [m["sigma_mm"] for m in fitted], rep, of="fitted", config=cfg)
        if held and all(m.get("sigma_mm") is not None for m in held):
            inflate = 1.0 + n_par / max(2 * len(fitted), 1)
            hfloor = floor_test([m["residual_mm"] for m in held], [m["sigma_mm"] for m in held],
                                rep, inflate=inflate, config=cfg, floor_dof=floor_dof)
            worst = max_error_test(held_ids, [m["residual_mm"] for m in held],
                                   [m["sigma_mm"] for m in held], rep, of="held-out",
                                   inflate=inflate, config=cfg)
    elif fitted:
        reasons.append((by_design or "check", "the marks carry no measurement noise "
                                              "(measured_mm given): the residual cannot be "
                                              "compared with a noise floor"))
    reasons += _floor_reasons(floor, hfloor, cfg)
    reasons += _max_error_reasons(worst, "mark", "look at that mark and the paper around it")
    return _Floors(floor, hfloor, worst, reasons)


def _structure_reasons(cal: CalibrationResult, effects: list,
                       marks: dict) -> list[tuple[str, str]]:
    """(status, sentence) for structure the model leaves: an ``unexplained`` effect, the
    scans for unnamed effects skipped, photos whose marks moved together, a printed grid
    that disagrees with the markers (``ready`` when the print was measured and the marks
    are against it, else ``check``)."""
    out: list[tuple[str, str]] = []
    unexplained = [e for e in effects if e.get("name") == "unexplained"]
    if unexplained:
        seen = "; ".join(unexplained[0].get("seen", [])) or "structure"
        out.append(("check", f"structure no candidate explains is left in the residual "
                             f"({seen})"))
    diagnosis = cal.diagnosis or {}
    skipped = (diagnosis.get("discovery") or {}).get("skipped")
    if skipped:
        out.append(("check", skipped))
    moved = [p.get("file", "?") for p in diagnosis.get("per_photo_offsets") or []
             if p.get("flagged")]
    if moved:
        out.append(("check", f"{len(moved)} photo(s) whose marks moved together beyond the "
                             "noise (a bad sheet mapping?): " + ", ".join(moved[:5])))
    sh = diagnosis.get("sheet_height") or {}
    as_ = sh.get("not_claimed_as")
    pr = cal.extra.get("print") or {}
    printed_measured = pr.get("source") in ("views", "survey") and pr.get("applied", True)
    if not sh.get("claimed") and as_ == "mapping" and printed_measured:
        # the sheet as printed was measured (#28): the grid is off its layout as the markers
        # were, and the marks are measured against the markers as printed
        off = [math.hypot(*m["local_minus_global_mm"]) for m in marks.values()
               if m.get("local_minus_global_mm") is not None]
        out.append(("ready", "the printed grid is off its layout " + (
            f"by up to {max(off):.3f} mm " if off else "") + "as the print is: the marks are "
            "measured against the markers as printed (calibration.json print)"))
    elif not sh.get("claimed") and as_ in ("lens", "mapping"):
        off = [math.hypot(*m["local_minus_global_mm"]) for m in marks.values()
               if m.get("local_minus_global_mm") is not None]
        size = f"by up to {max(off):.3f} mm " if off else ""
        out.append(("check", f"the printed grid disagrees with the markers' mapping {size}the "
                             "way " + ("a lens error does" if as_ == "lens" else
                                       "a mapping error does")
                    + " (not the paper's height): marks measured against the markers carry "
                    "that error; declare the camera's lens, or photograph from several "
                    "places"))
    return out


def _left_out_reasons(outliers: set, marks: dict) -> list[tuple[str, str]]:
    """``check`` for marks left out of the fit: outliers, marks that could not be trusted."""
    out = []
    if outliers:
        out.append(("check", f"{len(outliers)} mark(s) left out as outliers: "
                             + ", ".join(sorted(outliers)[:5])))
    unreliable = [k for k, m in marks.items() if m.get("status") == "unreliable"]
    if unreliable:
        out.append(("check", f"{len(unreliable)} mark(s) could not be trusted and were left "
                             "out: " + ", ".join(sorted(unreliable)[:5])))
    return out


@dataclass(frozen=True)
class _Accuracy:
    """The expected target error (95 % radius, mm; None: no figure), the (status,
    sentence) reasons about it and a target's std by part (:func:`_target_parts`)."""

    r95: float | None
    reasons: list[tuple[str, str]]
    parts: dict | None = None


def _accuracy(cal: CalibrationResult, marks: dict, n_par: int, rep: float,
              full: EstimatorConfig, by_design: str | None) -> _Accuracy:
    """The expected target error and the reasons it gives: no held-out figure, too few
    spare degrees of freedom (``by_design``'s level for a pilot), the print not measured
    (:func:`_print_part`), a held-out RMS well above the fitted one.

    With every fitted mark's noise known, it is the 95 % radius of a target's error whose
    per-axis std holds the calibration's covariance, the repeatability, what the model
    leaves and the print (:func:`_target_parts`, calibration.json ``verdict.target_std``; a
    planned target's ``std_mm`` is the same sum at its own place); else ``R95_PER_RMS``
    times the held-out RMS, the print added in quadrature."""
    cfg = full.verdict
    reasons: list[tuple[str, str]] = []

    def add(status, text, code=None):
        reasons.append((status, text) if code is None else (status, text, code))

    held_rms, fit_rms = _final(cal.validation_rms_mm), _final(cal.residual_rms_mm)
    r95 = R95_PER_RMS * held_rms if _finite(held_rms) else None
    if r95 is None:
        add("check", "no held-out marks and no cross-validation figure: the fitted RMS "
                     f"{fit_rms:.4f} mm understates the error on new targets"
            if _finite(fit_rms) else "no accuracy figure")
    n_fit = sum(m.get("role", "calibration") == "calibration" for m in marks.values())
    if marks and 2 * n_fit - n_par < cfg.min_spare_dof:
        add(by_design or "check",
            f"{n_fit} fitted marks leave {2 * n_fit - n_par} degrees of freedom, too few to "
            "test for backlash, gear-ratio or sheet effects")
    print_mm = _print_part(cal.extra.get("print"), add, full, by_design)
    parts = (_target_parts(cal, marks, n_par, rep, print_mm, _print_in_covariance(cal))
             if r95 is not None else None)
    _print_named(cal.extra.get("print"), parts, add, cfg)
    if parts is not None:
        r95 = R95_PER_STD * parts["total_mm"]
    elif r95 is not None and print_mm > 0:
        r95 = float(math.hypot(r95, R95_PER_STD * print_mm))
    if (r95 is not None and _finite(fit_rms) and fit_rms > 0
            and held_rms > cfg.heldout_warn_ratio * fit_rms):
        add("check", f"the held-out RMS ({held_rms:.4f} mm) is {held_rms / fit_rms:.1f} times "
                     "the fitted RMS: the model misses something on new poses")
    return _Accuracy(r95, reasons, parts)


def _print_part(pr: dict | None, add, full: EstimatorConfig, by_design: str | None) -> float:
    """The print's part of a target's std (mm, per axis) from calibration.json ``print``
    (#28). Measured (a survey, several camera places): its ``limit_mm`` (2-D RMS of what
    the measurement leaves, the same at every mark and not averaged by the fit) over
    sqrt 2. Not measured (``one place``: no survey and photos from fewer than
    ``as_printed.min_places`` places, a fixed camera among them) the print's deviation is
    unknown: every mark carries ``uncertainty.unmeasured_print_mm`` at least (what a
    printer does), or the larger part the markers show beyond the photos' mapping, and the
    run is ``check`` (``by_design``'s level for a pilot), with a fixed camera or not; so is
    a layout found but not applied for any reason but ``not significant`` (its solve
    stopped, it is not resolved or does not replicate: issue 37), with the size it found.
    A survey or several places that found the print on its layout measured it. No
    ``print`` block (marks given as ``measured_mm``): 0."""
    if not isinstance(pr, dict):
        return 0.0
    lim = pr.get("limit_mm")
    lim = float(lim) if _finite(lim) and lim > 0 else 0.0
    one_place = pr.get("source") == "one place"
    # a layout found but not applied measured the print only when it found it on its
    # layout (``not significant``); failed, unresolved or unreplicated, it tells nothing
    found_not_held = not one_place and print_not_measured(pr)
    if not print_not_measured(pr):
        return lim / math.sqrt(2.0)
    size = unmeasured_print_size(pr, full)
    if size > full.verdict.print_check_mm:
        seen = pr.get("seen_rms_mm")
        why = (f"the print field found does not hold ({pr.get('status')}: "
               f"{pr.get('reason')})" if found_not_held else
               f"no survey, and the photos come from fewer than "
               f"{full.as_printed.min_places} camera places; a fixed camera sees it from one, "
               "where it cannot be told from the lens")
        add(by_design or "check",
            f"the print's deviation from its layout is not measured ({why}): about "
            f"{size:.3f} mm RMS on every mark"
            + (f" (the markers show {seen:.3f} mm beyond the photos' mapping)"
               if _finite(seen) and seen > 0 else "")
            + ", in the expected target error: survey the sheet (vision-cal survey) or "
              "photograph it from several places", "print_one_place")
    return size / math.sqrt(2.0)


def _print_in_covariance(cal: CalibrationResult) -> float:
    """The per-axis std the print not measured adds, through the covariance, where the
    fitted marks' commands land (calibration.json ``print_in_covariance.at_marks_mm``,
    :func:`vision_cal.estimate.fit._print_in_covariance`; 0 without it)."""
    pc = cal.extra.get("print_in_covariance")
    x = pc.get("at_marks_mm") if isinstance(pc, dict) else None
    return float(x) if _finite(x) and x > 0 else 0.0


def _target_parts(cal: CalibrationResult, marks: dict, n_par: int, rep: float,
                  print_mm: float, in_cov: float = 0.0) -> dict | None:
    """A target's error, one std per axis, by part (calibration.json ``verdict.target_std``):
    ``calibration_mm`` (the fit's covariance at a mark: on average ``P / (2N - P)`` of the
    fitted residual's variance), ``repeatability_mm``, ``unexplained_mm`` (the residual's
    variance beyond the noise floor and the calibration's part, from the fitted marks,
    leverage corrected, and the held-out ones - validation marks, else the
    cross-validation figure - pooled by their degrees of freedom; 0 when noise explains
    it), ``print_mm`` and ``total_mm`` (their root sum of squares), ``from`` (the marks it
    was read on). None unless every fitted mark carries its noise. ``in_cov``: the print
    not measured carried in the covariance (:func:`_print_in_covariance`): counted once,
    in the calibration's part, and taken off the print's (``print_mm`` what is left of
    it), so that the total is the same and a planned target's ``std_mm``, whose
    calibration part is the covariance's at its command, does not count it twice."""
    outl = set(cal.outliers or [])
    fit = [m for k, m in marks.items() if m.get("role", "calibration") == "calibration"
           and m.get("status", "ok") == "ok" and m.get("residual_mm") is not None
           and k not in outl]
    if not fit or any(m.get("sigma_mm") is None for m in fit):
        return None
    n = len(fit)
    res = np.array([m["residual_mm"] for m in fit], float).reshape(-1, 2)
    sig2 = float(np.mean([m["sigma_mm"] ** 2 for m in fit]))
    mse = float(np.mean(res**2))                       # per axis
    dof_f = max(2 * n - n_par, 1)
    c2 = mse * n_par / dof_f
    u2_fit = mse * 2 * n / dof_f - sig2 - rep**2
    held = [m for m in marks.values() if m.get("role") == "validation"
            and m.get("status", "ok") == "ok" and m.get("residual_mm") is not None
            and m.get("sigma_mm") is not None]
    vr = _final(cal.validation_rms_mm)
    if len(held) >= 3:
        h = np.array([m["residual_mm"] for m in held], float).reshape(-1, 2)
        u2_held = (float(np.mean(h**2)) - float(np.mean([m["sigma_mm"] ** 2 for m in held]))
                   - rep**2 - c2)
        dof_h, source = 2 * len(held), f"{n} fitted and {len(held)} held-out marks"
    elif _finite(vr):
        u2_held, dof_h = vr**2 / 2 - sig2 - rep**2 - c2, 2 * n
        source = f"{n} fitted marks and their cross-validation"
    else:
        u2_held, dof_h, source = 0.0, 0, f"{n} fitted marks"
    u2 = max((dof_f * u2_fit + dof_h * u2_held) / (dof_f + dof_h), 0.0)
    c2 += in_cov**2
    print_mm = math.sqrt(max(print_mm**2 - in_cov**2, 0.0))
    total = math.sqrt(c2 + rep**2 + u2 + print_mm**2)
    return {"calibration_mm": math.sqrt(c2), "repeatability_mm": rep,
            "unexplained_mm": math.sqrt(u2), "print_mm": print_mm, "total_mm": total,
            "from": source}


def _print_named(pr: dict | None, parts: dict | None, add, cfg) -> None:
    """The print measured (several places, a survey; applied, or seen and kept as declared)
    yet leaving beyond ``cfg.print_check_mm`` on every mark is named as a cause of the
    target error of its own (issue 37), ``check`` where it is at least the rest of it
    (``parts``: :func:`_target_parts`), else at the ``ready`` level."""
    if not isinstance(pr, dict) or pr.get("source") == "one place":
        return
    lim = pr.get("limit_mm")
    if not _finite(lim) or lim <= cfg.print_check_mm:
        return
    if pr.get("applied") is False and pr.get("status") not in (None, "not significant"):
        return   # not measured: _print_part said so
    rest2 = (None if parts is None else
             parts["total_mm"] ** 2 - parts["print_mm"] ** 2)
    level = "check" if rest2 is None or parts["print_mm"] ** 2 >= rest2 else "ready"
    if pr.get("applied") is False:
        add(level, f"the print: the {pr.get('n_places', '?')} camera places see it "
                   f"{pr.get('rms_mm', float('nan')):.3f} mm RMS off its layout, within what "
                   f"they cannot resolve ({pr.get('unresolved_mm', float('nan')):.3f} mm): "
                   f"the declared layout is kept and about {lim:.3f} mm RMS stays on every "
                   "mark, in the expected target error: declare the camera's lens, "
                   "photograph from more places, or survey the sheet", "print")
    else:
        add(level, f"the print: {pr.get('field_rms_mm', float('nan')):.3f} mm RMS off its "
                   f"layout, measured from {pr.get('n_places', '?')} camera places, leaves "
                   f"about {lim:.3f} mm RMS on every mark (what the views cannot tell from "
                   "the lens and the paper's shape), in the expected target error: declare "
                   "the camera's lens, or survey the sheet from more places", "print")


def judge_camera_poses(residual_mm, sigma_mm, heldout_mm, *, n_params: float,
                       repeatability_mm: float | None = None,
                       reasons: list[tuple[str, str]] = (),
                       config: VerdictConfig | None = None, ids=None,
                       heldout_inflate=None, repeat_pairs=(),
                       valid_for: dict | None = None) -> Verdict:
    """The verdict of a calibration from the arm camera's photos (``vision-cal handeye``):
    the same gate, status rule and block as :func:`judge`, its "marks" being the flange
    positions the photos imply. ``residual_mm`` (N, 2): each photo's in-plane flange
    position against the model's; ``sigma_mm`` (N,): the per-axis std the marker corners'
    noise alone gives it (the measurer's noise), the robot's repeatability added as for
    marks; ``n_params`` the parameters those residuals consume (the hat matrix's trace over
    them); ``heldout_mm`` (N, 2) leave-one-photo-out residuals, judged against the same
    floor and giving ``expected_target_error_mm``; ``reasons`` (status, sentence) the
    caller's own (parameters the poses do not separate, an undetermined lens); ``config``
    the gate's thresholds (default ``DEFAULT.verdict``); ``ids`` (N,) the photos' names
    (default their indices), naming the largest held-out error, judged as :func:`judge`
    judges a mark's (``max_target_error``). ``heldout_inflate`` (N,): each leave-one-out
    residual's variance factor, 1 / (1 - leverage) (None: the mean leverage's
    1 + P / 2N, which a pose the fit leans on exceeds: its held-out residual was judged
    too large against the floor). ``repeat_pairs``: (i, j) photos taken at the same
    command from the same sides: with ``min_repeat_pairs`` of them the robot's
    repeatability is measured from them (their flange residuals differ by noise alone,
    as :func:`repeatability_from_repeats` does for marks), better than a catalogue
    figure or the default: the floor is almost all repeatability (the corners' noise
    gives the flange 0.001 mm where the robot gives 0.01), so a robot 1.4 times less
    repeatable than assumed reads 1.4 times its floor with nothing missing. ``valid_for``:
    calibration.json's block (``dataset/valid_for.build`` of the poses), judged as
    :func:`judge` judges the pen's: an effect the poses could not identify (a joint reached
    from one side) is ``check`` with what to draw, the status inside it
    ``within_valid_for``."""
    cfg = config or DEFAULT.verdict
    rep = cfg.default_repeatability_mm if repeatability_mm is None else float(repeatability_mm)
    source = "default" if repeatability_mm is None else "robot block"
    res = np.asarray(residual_mm, float).reshape(-1, 2)
    sig = np.asarray(sigma_mm, float).reshape(-1)
    pairs = [(int(i), int(j)) for i, j in repeat_pairs]
    if len(pairs) >= cfg.min_repeat_pairs:
        terms = [float((res[i] - res[j]) @ (res[i] - res[j])) / 2 - sig[i] ** 2 - sig[j] ** 2
                 for i, j in pairs]
        rep = math.sqrt(max(float(np.mean(terms)) / 2, 0.0))
        source = f"{len(pairs)} pairs of photos taken at the same command"
    n, p = len(res), int(round(n_params))
    floor = floor_test(res, sigma_mm, rep, n_params=p, config=cfg)
    inflate = (1.0 + p / max(2 * n, 1) if heldout_inflate is None
               else np.asarray(heldout_inflate, float).reshape(-1))
    hfloor = floor_test(heldout_mm, sigma_mm, rep, inflate=inflate, config=cfg)
    worst = max_error_test(list(range(n)) if ids is None else list(ids), heldout_mm, sigma_mm,
                           rep, of="held-out", inflate=inflate, config=cfg)
    outside = _coded(valid_for_reasons(valid_for), "not_identified")
    found = _coded(list(reasons), "camera") + outside + _coded(
        _floor_reasons(floor, hfloor, cfg) + _max_error_reasons(
            worst, "photo", "look at that photo's markers and the pose it was taken at"),
        "noise_floor")
    if 2 * n - p < cfg.min_spare_dof:
        found.append(("check", f"{n} photos leave {2 * n - p} degrees of freedom to compare "
                               "with the noise floor: add poses", "accuracy"))
    held = np.asarray(heldout_mm, float).reshape(-1, 2)
    r95 = R95_PER_RMS * float(np.sqrt(np.mean(np.sum(held**2, axis=1)))) if n else None
    v = _verdict(found, r95, floor, hfloor, rep, source, worst)
    if outside:   # the status inside valid_for, as the pen's verdict says it
        inner = _verdict([r for r in found if r not in outside], r95, floor, hfloor, rep,
                         source, worst)
        v = replace(v, within_valid_for=inner.status)
    return v


def _coded(reasons, code: str) -> list[tuple[str, str, str]]:
    """(status, sentence, kind) of (status, sentence[, kind]) reasons: ``code`` where none
    is given."""
    return [(r[0], r[1], r[2] if len(r) > 2 else code) for r in reasons]


def _verdict(reasons, r95, floor, hfloor, rep, source, worst) -> Verdict:
    """The block from the (status, sentence[, kind]) reasons found: the worst status wins
    (``ready`` when none), its sentences first, each with its kind (``other`` unsaid)."""
    reasons = _coded(reasons, "other")
    status = max((r[0] for r in reasons), key=_RANK.get, default="ready")
    ranked = sorted(reasons, key=lambda r: -_RANK[r[0]])
    return Verdict(status, r95, floor.ratio if floor is not None else None,
                   tuple(r[1] for r in ranked),
                   floor.to_json() if floor is not None else None,
                   hfloor.to_json() if hfloor is not None else None, rep, source,
                   worst.to_json() if worst is not None else None,
                   reason_codes=tuple(r[2] for r in ranked),
                   reason_levels=tuple(r[0] for r in ranked))


@dataclass(frozen=True)
class PlacementAgreement:
    """One placement's residual against the other placements' (``calibrate --joint``):
    ``ratio = sqrt(F)``, F the ratio of its residual variance per degree of freedom to the
    others' pooled (in noise units when every mark's noise is known, else in mm)."""

    name: str
    n_marks: int
    rms_mm: float
    ratio: float
    p_value: float
    units: str              # "noise" | "mm"
    beyond: bool

    def to_json(self) -> dict:
        return {"n_marks": self.n_marks, "rms_mm": self.rms_mm, "ratio_to_others": self.ratio,
                "p_value": self.p_value, "units": self.units, "disagrees": self.beyond}


def judge_placements(names, residuals_mm, sigmas_mm, heldout_mm, *, n_params: int,
                     repeatability_mm: float | None = None,
                     reasons: list[tuple[str, str]] = (),
                     config: VerdictConfig | None = None
                     ) -> tuple[Verdict, list[Verdict], list[PlacementAgreement | None]]:
    """The verdict of one robot fitted from several placements (``calibrate --joint``) and
    of each placement's calibration, with the same gate, status rule and block as
    :func:`judge`. ``residuals_mm`` / ``heldout_mm``: per placement (N_k, 2) fitted and
    cross-validated residuals; ``sigmas_mm``: per placement (N_k,) the measurer's noise, or
    None (marks given as ``measured_mm``); ``n_params`` the joint fit's parameters (3 per
    placement for its sheet pose, the rest shared: a placement is charged its pose and its
    share of the rest by its marks); ``reasons`` (status, sentence) of the fit itself
    (structure left), said in every verdict.

    A placement **disagrees with the others** when its residual variance per degree of
    freedom exceeds the others' pooled by more than noise explains (F-test at
    ``floor_alpha``) and by more than ``floor_ratio_tol`` in scale: the same robot cannot
    have drawn it on a sheet lying still (another robot, a moved sheet, a wrong robot
    block). It is named in the joint verdict (``not reliable`` at ``not_reliable_ratio``
    and beyond: its marks pull the shared parameters) and in its own; the other
    placements' verdicts say their shared parameters were fitted with it."""
    pl = _placements(names, residuals_mm, sigmas_mm, heldout_mm, n_params, repeatability_mm,
                     config or DEFAULT.verdict)
    agree = _agreements(pl)
    bad = [a for a in agree if a is not None and a.beyond]
    no_noise = [] if pl.known else [("check", "some placements' marks carry no measurement "
                                              "noise (measured_mm given): the residual "
                                              "cannot be compared with a noise floor")]
    joint = _joint_placements_verdict(pl, list(reasons) + [
        _disagree_sentence(a, pl.cfg) for a in bad] + no_noise)
    each = []
    for k in range(len(pl.res)):
        mine = [_disagree_sentence(a, pl.cfg) for a in bad if a.name == pl.names[k]]
        others = [a.name for a in bad if a.name != pl.names[k]]
        if others:
            mine.append(("check", f"the shared parameters were fitted with placement(s) "
                                  f"{', '.join(others)}, which disagree with the others"))
        each.append(_placement_verdict(pl, k, list(reasons) + mine + no_noise))
    return joint, each, agree


@dataclass(frozen=True)
class _Placements:
    """Several placements' residuals, as :func:`judge_placements` judges them: per
    placement the fitted and held-out residuals (N_k, 2), the measurer's noise (N_k,) or
    None, its marks, the parameters it is charged, its residual sum of squares (in noise
    units when every noise is known, else mm) and degrees of freedom; the joint fit's
    parameters, the repeatability and its source, the thresholds."""

    names: tuple[str, ...]
    res: list
    held: list
    sigmas: list
    n_k: list[int]
    p_k: list[float]
    ssr: list[float]
    dof: list[float]
    known: bool             # every placement's marks carry their noise
    n_params: int
    rep: float
    source: str
    cfg: VerdictConfig


def _placements(names, residuals_mm, sigmas_mm, heldout_mm, n_params: int,
                repeatability_mm: float | None, cfg: VerdictConfig) -> _Placements:
    """The placements' arrays and what each is charged: its sheet pose (3 parameters) and
    the shared parameters' share by its marks; the repeatability is the robot block's
    (``repeatability_mm``) or the config's default."""
    rep = cfg.default_repeatability_mm if repeatability_mm is None else float(repeatability_mm)
    source = "default" if repeatability_mm is None else "robot block"
    res = [np.asarray(r, float).reshape(-1, 2) for r in residuals_mm]
    held = [np.asarray(h, float).reshape(-1, 2) for h in heldout_mm]
    n_k = [len(r) for r in res]
    n_all, n_place = sum(n_k), len(res)
    shared = max(n_params - 3 * n_place, 0)
    p_k = [3 + shared * n / max(n_all, 1) for n in n_k]
    known = all(s is not None for s in sigmas_mm)
    var = [(np.asarray(s, float).reshape(-1) ** 2 + rep**2) if known else np.ones(n)
           for s, n in zip(sigmas_mm, n_k)]
    ssr = [float(np.sum(r**2 / v[:, None])) for r, v in zip(res, var)]
    dof = [2 * n - p for n, p in zip(n_k, p_k)]
    return _Placements(tuple(str(n) for n in names), res, held, list(sigmas_mm), n_k, p_k, ssr,
                       dof, known, n_params, rep, source, cfg)


def _agreements(pl: _Placements) -> list[PlacementAgreement | None]:
    """Each placement's residual against the others' pooled (F-test at ``floor_alpha``,
    beyond also ``floor_ratio_tol`` in scale); None where there is nothing to compare (one
    placement, no degrees of freedom, a zero residual)."""
    agree: list[PlacementAgreement | None] = []
    n_place = len(pl.res)
    for k in range(n_place):
        o_ssr = sum(pl.ssr) - pl.ssr[k]
        o_dof = sum(pl.dof) - pl.dof[k]
        if n_place < 2 or pl.dof[k] <= 0 or o_dof <= 0 or o_ssr <= 0:
            agree.append(None)
            continue
        F = (pl.ssr[k] / pl.dof[k]) / (o_ssr / o_dof)
        p = float(stats.f.sf(F, pl.dof[k], o_dof))
        ratio = math.sqrt(F)
        agree.append(PlacementAgreement(
            pl.names[k], pl.n_k[k], float(np.sqrt(np.mean(np.sum(pl.res[k]**2, axis=1)))),
            ratio, p, "noise" if pl.known else "mm",
            bool(p < pl.cfg.floor_alpha and ratio > pl.cfg.floor_ratio_tol)))
    return agree


def _disagree_sentence(a: PlacementAgreement, cfg: VerdictConfig) -> tuple[str, str]:
    """(status, sentence) naming a placement that disagrees with the others: ``not
    reliable`` at ``not_reliable_ratio`` and beyond, else ``check``."""
    return ("not reliable" if a.ratio >= cfg.not_reliable_ratio else "check",
            f"placement {a.name} disagrees with the others: its marks miss the shared robot "
            f"by {a.rms_mm:.4f} mm RMS, {a.ratio:.1f} times the others' residual "
            f"({'in noise units' if a.units == 'noise' else 'in mm'}, p = {a.p_value:.2g}); "
            "the same robot, the sheet taped still, the right session.json? calibrate it "
            "alone to compare, or leave it out")


def _joint_placements_verdict(pl: _Placements, reasons: list[tuple[str, str]]) -> Verdict:
    """The joint fit's verdict: every placement's marks against the floor (when every
    noise is known), the largest held-out error named ``placement/index``, too few spare
    degrees of freedom, and ``reasons`` (the fit's and the placements')."""
    cfg, rep, n_params = pl.cfg, pl.rep, pl.n_params
    n_all = sum(pl.n_k)
    floor = hfloor = worst = None
    if pl.known:
        sig = np.concatenate([np.asarray(s, float).reshape(-1) for s in pl.sigmas])
        floor = floor_test(np.concatenate(pl.res), sig, rep, n_params=n_params, config=cfg)
        inflate = 1.0 + n_params / max(2 * n_all, 1)
        hfloor = floor_test(np.concatenate(pl.held), sig, rep, inflate=inflate, config=cfg)
        ids = [f"{pl.names[k]}/{i}" for k in range(len(pl.res)) for i in range(pl.n_k[k])]
        worst = max_error_test(ids, np.concatenate(pl.held), sig, rep, of="held-out",
                               inflate=inflate, config=cfg)
    found = (list(reasons) + _floor_reasons(floor, hfloor, cfg)
             + _max_error_reasons(worst, "mark", "look at that mark and the paper around it"))
    if 2 * n_all - n_params < cfg.min_spare_dof:
        found.append(("check", f"{n_all} marks leave {2 * n_all - n_params} degrees of freedom, "
                               "too few to test for effects"))
    allh = np.concatenate(pl.held)
    r95 = R95_PER_RMS * float(np.sqrt(np.mean(np.sum(allh**2, axis=1)))) if len(allh) else None
    return _verdict(found, r95 if r95 is not None and math.isfinite(r95) else None,
                    floor, hfloor, rep, pl.source, worst)


def _placement_verdict(pl: _Placements, k: int, reasons: list[tuple[str, str]]) -> Verdict:
    """Placement ``k``'s own verdict: its marks against the floor with the parameters it
    is charged (when every noise is known), its largest held-out error, and ``reasons``
    (the fit's, and what its or the other placements' disagreement says of it)."""
    cfg, rep = pl.cfg, pl.rep
    fk = hk = wk = None
    if pl.known:
        s = np.asarray(pl.sigmas[k], float).reshape(-1)
        fk = floor_test(pl.res[k], s, rep, n_params=int(round(pl.p_k[k])), config=cfg)
        infl = 1.0 + pl.p_k[k] / max(2 * pl.n_k[k], 1)
        hk = floor_test(pl.held[k], s, rep, inflate=infl, config=cfg)
        wk = max_error_test(list(range(pl.n_k[k])), pl.held[k], s, rep, of="held-out",
                            inflate=infl, config=cfg)
    rk = list(reasons) + _floor_reasons(fk, hk, cfg) + _max_error_reasons(
        wk, "mark", "look at that mark and the paper around it")
    e95 = (R95_PER_RMS * float(np.sqrt(np.mean(np.sum(pl.held[k]**2, axis=1))))
           if pl.n_k[k] else None)
    return _verdict(rk, e95 if e95 is not None and math.isfinite(e95) else None,
                    fk, hk, rep, pl.source, wk)
