"""The calibration pipeline: dataset -> measure -> calibrate -> diagnose -> calibration.json.

:func:`calibrate_dataset` is what ``vision-cal DIR --out OUT`` runs, one stage a
function: :func:`measure_marks` -> :func:`fit_lsq` or :func:`fit_paper` -> :func:`document`.
Each fit method returns its blocks of calibration.json (:class:`_Fitted`, keyed by the
fields of :class:`vision_cal.dataset.calibration_result.CalibrationResult`);
:func:`document` builds the one :class:`CalibrationResult` from them and the measurement,
and it is written once. Summaries and reports are rendered from the written files. A new
calibration method is one more ``fit_*`` returning ``_Fitted``.
"""

from __future__ import annotations

import logging
from contextlib import contextmanager
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from vision_cal.calibrate.joint4 import add_tool, fit_joint4_paper, joint4_stage
from vision_cal.model.lsq import Fit
from vision_cal.calibrate.paper import PaperResult, paper_method
from vision_cal.calibrate.paper_scale import check_bars, paper_scale_block
from vision_cal.calibrate.plausible import check_plausible
from vision_cal.model.tool_fit import folded_statement
from vision_cal.camera.fixed import cameras_json
from vision_cal.config import DEFAULT, METHODS, EstimatorConfig
from vision_cal.dataset.calibration_result import CalibrationResult, ModelRms
from vision_cal.dataset.covariance import covariance_json
from vision_cal.dataset.io import as_json, read_json
from vision_cal.dataset.nominal import nominal_blocks
from vision_cal.dataset.session import Session, load_session
from vision_cal.dataset.sheet_identity import sheet_identity
from vision_cal.dataset.valid_for import build as valid_for_block
from vision_cal.diagnose.candidates import default_candidates
from vision_cal.diagnose.discover import trace
from vision_cal.diagnose.photos import per_photo_offsets
from vision_cal.diagnose.replicate import replicate
from vision_cal.diagnose.select import Diagnosis, diagnose
from vision_cal.diagnose.sheet import NOT_FLAT, PRINT_BETWEEN, smooth_residual
from vision_cal.diagnose.verdict import judge
from vision_cal.errors import CalibrationError, VisionCalError
from vision_cal.model.kinematics import forward
from vision_cal.workflows.measure_folder import measure_folder
from vision_cal.measure.print_stage import print_field_cov
from vision_cal.measure.printed import printed_content_json
from vision_cal.measure.survey import load_survey
from vision_cal.measure.types import Measurement
from vision_cal.model.robot import JointBacklash, RobotModel, SheetAffine
from vision_cal.workflows.report_data import add_to_calibration
from vision_cal.model.rms import rms_2d
from vision_cal.progress import bar

log = logging.getLogger(__name__)

#: marks from which the fit + diagnosis and the writing of calibration.json each print a
#: progress line when they start and end (a marks CSV of 2,000 marks takes seconds, of
#: 100,000 minutes: docs/format.md, "Marks from other instruments")
PROGRESS_MARKS = 2000


@dataclass(frozen=True)
class MarkData:
    """Measured marks in plan order. Arrays (N, 2) unless noted."""

    ids: tuple[str, ...]
    q_deg: np.ndarray
    approach: np.ndarray
    xy_mm: np.ndarray
    sigma_mm: np.ndarray | None  # (N,) per-axis standard deviation, when measured by camera
    roles: tuple[str, ...]
    joint4: np.ndarray | None = None  # (N, 2) [j4_deg, approach4] when the session uses joint 4

    @property
    def q_model(self) -> np.ndarray:
        """Joints as the model takes them: (N, 2), or (N, 3) ``[q1, q2, q4]`` with joint 4."""
        return self.q_deg if self.joint4 is None else np.column_stack([self.q_deg,
                                                                        self.joint4[:, 0]])

    @property
    def approach_model(self) -> np.ndarray:
        """Approach signs as the model takes them: (N, 2), or (N, 3) with joint 4's."""
        return self.approach if self.joint4 is None else np.column_stack([self.approach,
                                                                          self.joint4[:, 1]])

    def select(self, role: str) -> "MarkData":
        k = np.array([r == role for r in self.roles], dtype=bool)
        return MarkData(tuple(i for i, s in zip(self.ids, k) if s), self.q_deg[k],
                        self.approach[k], self.xy_mm[k],
                        None if self.sigma_mm is None else self.sigma_mm[k],
                        tuple(r for r, s in zip(self.roles, k) if s),
                        None if self.joint4 is None else self.joint4[k])


@dataclass(frozen=True)
class CalibrationRun:
    """One run in memory: the result as written (``result``; ``document`` its JSON), where,
    and what only the live run has (the selection's :class:`Diagnosis` for ``lsq``, the
    circle fits for ``paper``, the photos' measurement, the calibrated model)."""

    session: Session
    result: CalibrationResult
    out_path: Path
    model: RobotModel                 # the calibrated robot (what load_calibration reads back)
    diagnosis: Diagnosis | None = None
    paper: PaperResult | None = None
    measurement: Measurement | None = None

    @cached_property
    def document(self) -> dict:
        """calibration.json as written (``result.to_json()``)."""
        return self.result.to_json()


def collect_marks(session: Session, measurement=None) -> tuple[MarkData, list[str]]:
    """Marks with a position: ``measured_mm`` from the session, else from the photos."""
    app = session.approach
    j4 = np.column_stack([session.j4_deg, session.approach4]) if session.uses_joint4 else None
    ids, q, a, xy, sig, roles, missing, k4 = [], [], [], [], [], [], [], []
    for i, m in enumerate(session.marks):
        if measurement is not None and m.id in measurement.marks:
            mm = measurement.marks[m.id]
            if mm.status != "ok":
                continue   # kept in calibration.json with its reason, left out of the fit
            pos = np.asarray(mm.xy_mm, dtype=float)
            s = float(np.sqrt(np.trace(np.asarray(mm.cov_mm2)) / 2))
        elif m.measured_mm is not None:   # its stated accuracy, when given (issue 32)
            pos = np.asarray(m.measured_mm, dtype=float)
            s = np.nan if m.measured_sigma_mm is None else float(m.measured_sigma_mm)
        else:
            missing.append(m.id)
            continue
        ids.append(m.id)
        q.append(m.joints_deg)
        a.append(app[i])
        xy.append(pos)
        sig.append(s)
        roles.append(m.role)
        k4.append(i)
    sigma = np.array(sig) if len(sig) and np.all(np.isfinite(sig)) else None
    return MarkData(tuple(ids), np.array(q, float).reshape(-1, 2), np.array(a, float).reshape(-1, 2),
                    np.array(xy, float).reshape(-1, 2), sigma, tuple(roles),
                    None if j4 is None else j4[np.array(k4, dtype=int)]), missing


def photo_reasons(measurement, *, top: int = 3) -> str:
    """The most common reasons photos were skipped, counted, with one example each:
    ``"5 of 6 photos skipped: 4 wrong sheet (img_000.png: wrong sheet: ...), 1 blank image"``.
    Reasons are grouped by what comes before their first colon."""
    skipped = [im for im in measurement.images if im.status != "ok"]
    if not skipped:
        return ""
    groups: dict[str, list] = {}
    for im in skipped:
        groups.setdefault((im.reason or "no reason").split(":", 1)[0], []).append(im)
    ranked = sorted(groups.items(), key=lambda kv: -len(kv[1]))
    parts = [f"{len(ims)} {kind} ({ims[0].file}: {ims[0].reason})" if i == 0 else
             f"{len(ims)} {kind}" for i, (kind, ims) in enumerate(ranked[:top])]
    more = f", {len(ranked) - top} other reasons" if len(ranked) > top else ""
    return (f"{len(skipped)} of {len(measurement.images)} photos skipped: "
            + ", ".join(parts) + more)


def _why_unmeasured(measurement) -> str:
    """Why photos gave no marks (appended to the "too few marks" error), or ""."""
    if measurement is None:
        return ""
    why = photo_reasons(measurement)
    ok = [im for im in measurement.images if im.status == "ok"]
    if ok:
        dots = sum(im.n_dots for im in ok)
        rejected: dict[str, int] = {}
        for im in ok:
            for k, v in (im.rejected or {}).items():
                rejected[k] = rejected.get(k, 0) + v
        top = sorted(rejected.items(), key=lambda kv: -kv[1])[:3]
        seen = (f"{len(ok)} photo(s) measured found {dots} pen mark(s)"
                + (" and rejected " + ", ".join(f"{v} {k}" for k, v in top) if top else "")
                + (f", {len(measurement.unassigned)} not matched to any planned mark"
                   if measurement.unassigned else ""))
        why = f"{why}; {seen}" if why else seen
    return f"; {why}" if why else ""


def _paper_std(q, xy, sigma_mm: float) -> tuple[dict, np.ndarray]:
    """Std of the paper's parameters by linear propagation of mark noise ``sigma_mm``,
    and their covariance (6, 6) in internal units."""
    G = np.zeros((6, xy.size))
    h = 1e-4
    for k in range(xy.size):
        d = np.zeros(xy.size)
        d[k] = h
        vp = paper_method(q, xy + d.reshape(xy.shape)).or_raise().params.vector
        vm = paper_method(q, xy - d.reshape(xy.shape)).or_raise().params.vector
        G[:, k] = (vp - vm) / (2 * h)
    cov = G @ G.T * sigma_mm**2 if np.isfinite(sigma_mm) else np.full((6, 6), np.nan)
    s = np.sqrt(np.diag(cov))
    return ({"L1_mm": s[0], "L2_mm": s[1], "joint_zero_deg": [np.degrees(s[2]), np.degrees(s[3])],
             "base_mm": [s[4], s[5]]}, cov)


@dataclass(frozen=True)
class _Fitted:
    """What one calibration method leaves for the document: its blocks of calibration.json
    (``blocks``: :class:`CalibrationResult` field name -> JSON value), the final model and
    each mark's residual under the final and the base model."""

    blocks: dict
    model: RobotModel
    residual_all: dict
    residual_base: dict
    diagnosis: Diagnosis | None = None
    paper: PaperResult | None = None


def calibrate_dataset(folder, *, out_dir, method: str = "lsq", jobs: int | None = None,
                      progress: bool = False, truth: bool = False,
                      config: EstimatorConfig | None = None, survey=None,
                      bars_mm=None) -> CalibrationRun:
    """Measure (if needed), calibrate and diagnose a dataset folder; write calibration.json.

    The stages: :func:`measure_marks`, then :func:`fit_paper` or :func:`fit_lsq`, then
    :func:`document`. ``config``: the estimator's thresholds (:mod:`vision_cal.config`;
    default ``DEFAULT``), recorded in calibration.json's ``config``. ``survey``: the sheet
    as printed (survey.json's path, or None: a ``survey.json`` beside session.json's sheet
    is not looked for here; :func:`vision_cal.measure.survey.find_survey` does that).
    ``bars_mm``: the sheet's two printed 100 mm bars as measured (x, y), in place of
    ``sheet.printed.measured_bar_mm`` (``calibrate --bars-mm``; calibration.json
    ``printer_scale`` and ``paper_scale``)."""
    if method not in METHODS:
        raise VisionCalError(f"unknown method {method!r} (expected one of {', '.join(METHODS)})")
    config = config or DEFAULT
    if bars_mm is not None:
        bars_mm = check_bars(bars_mm)
    # a folder, or a session already read (a marks CSV: vision_cal.dataset.marks_csv)
    session = folder if isinstance(folder, Session) else load_session(folder)
    out_dir = Path(out_dir)
    measurement, data, missing = measure_marks(session, out_dir=out_dir, jobs=jobs,
                                               progress=progress, config=config,
                                               survey=None if survey is None
                                               else load_survey(survey, session.sheet))
    cal, val = data.select("calibration"), data.select("validation")
    n_marks = len(cal.ids) + len(val.ids)
    with _long_stage(progress, n_marks, "fit + diagnosis"):
        if cal.joint4 is not None and len(np.unique(np.round(cal.joint4[:, 0], 6))) > 1:
            if method == "paper":
                fitted = _Fitted(*fit_joint4_paper(cal, val))
            else:   # the tool and joint 4's effects first, then the diagnosis with them
                stage = joint4_stage(cal, config)
                fitted = fit_lsq(session, cal, val, measurement, config, stage.effects)
                add_tool(fitted.blocks, fitted.diagnosis, stage)
        else:
            fitted = (fit_paper(cal, val, config) if method == "paper"
                      else fit_lsq(session, cal, val, measurement, config))
            if cal.joint4 is not None:   # one j4_deg: the tool is folded into L2 and z2
                fitted = replace(fitted, blocks={**fitted.blocks, "tool": folded_statement(
                    cal.joint4[:, 0], session.robot.tool_mm or (0.0, 0.0))})
    with _long_stage(progress, n_marks, "calibration.json"):
        result = document(session, data, missing, measurement, fitted, method=method,
                          config=config, truth=truth, bars_mm=bars_mm)
        check_plausible(result.to_json(), session)  # radians, metres: stop before any file
        out_path = result.write(out_dir / "calibration.json")
    log.info("wrote %s", out_path)
    return CalibrationRun(session, result, out_path, fitted.model, fitted.diagnosis,
                          fitted.paper, measurement)


@contextmanager
def _long_stage(progress: bool, n_marks: int, desc: str):
    """A progress line as the stage ``desc`` starts and ends, from ``PROGRESS_MARKS``
    marks (with ``progress``); a stage that fails ends its line at 0 marks."""
    line = bar(progress and n_marks >= PROGRESS_MARKS, total=n_marks, unit="mark", desc=desc)
    try:
        yield
        line.update(n_marks)
    finally:
        line.close()


def measure_marks(session: Session, *, out_dir: Path, jobs: int | None = None,
                  progress: bool = False, config: EstimatorConfig = DEFAULT, survey=None
                  ) -> tuple[Measurement | None, MarkData, list[str]]:
    """(measurement or None, MarkData, missing ids): the photos measured when a mark has
    no ``measured_mm``; fewer than 3 calibration marks is a :class:`CalibrationError` that
    names why photos gave none."""
    measurement = None
    if any(m.measured_mm is None for m in session.marks):
        measurement = measure_folder(session, out_dir=out_dir, jobs=jobs, progress=progress,
                                     config=config, survey=survey)
    data, missing = collect_marks(session, measurement)
    n_cal = len(data.select("calibration").ids)
    if n_cal < 3:
        raise CalibrationError(f"{n_cal} calibration marks were measured "
                               f"({len(missing)} missing): at least 3 are needed"
                               + _why_unmeasured(measurement), file=str(session.path))
    return measurement, data, missing


def fit_paper(cal: MarkData, val: MarkData, config: EstimatorConfig = DEFAULT) -> _Fitted:
    """The seed paper's circle method on the calibration marks; validation marks scored."""
    paper = paper_method(cal.q_deg, cal.xy_mm).or_raise()   # no circles: the run ends
    params = paper.params
    noise_mm = Fit.from_estimate(cal.q_deg, cal.xy_mm, approach=cal.approach, robust=False,
                                 config=config).or_raise().residual_scale  # unweighted: mm
    std, cov = _paper_std(cal.q_deg, cal.xy_mm, noise_mm)
    res_cal = cal.xy_mm - _predict(params, cal)
    res_val = val.xy_mm - _predict(params, val) if len(val.ids) else np.zeros((0, 2))
    rv = rms_2d(res_val) if len(val.ids) else None
    blocks = dict(params=params.to_json(), std=std, effects=[],
                  residual_rms_mm=ModelRms(rms_2d(res_cal), rms_2d(res_cal)),
                  validation_rms_mm=ModelRms(rv, rv, "validation marks" if len(val.ids)
                                             else "none"),
                  circles={"base": paper.circle_base.to_json(),
                           "elbow": paper.circle_elbow.to_json()},
                  covariance=covariance_json(RobotModel(params).param_labels(), cov))
    residual_all = {i: r for i, r in zip(cal.ids, res_cal)}
    residual_all.update({i: r for i, r in zip(val.ids, res_val)})
    return _Fitted(blocks, RobotModel(params), residual_all, residual_all, paper=paper)


def fit_lsq(session: Session, cal: MarkData, val: MarkData, measurement,
            config: EstimatorConfig, base_effects: tuple = ()) -> _Fitted:
    """Least squares, then the diagnosis that adds the effects the base model lacks.
    ``base_effects``: the tool and joint-4 effects every model holds (marks at several
    ``j4_deg``, :mod:`vision_cal.calibrate.joint4`); the joints then carry joint 4."""
    not_flat = (measurement is not None and measurement.height_map is not None
                and measurement.height_map.claimed)
    cands = None
    if not_flat:  # a sheet that is not flat is its height, never an affine sheet
        cands = [c for c in default_candidates() if not isinstance(c.effect, SheetAffine)]
        if any(m.reference != "grid" for m in measurement.marks.values()):
            # marks not measured against the paper's own grid keep some of its height:
            # only effects that are not smooth over the sheet (backlash flips with the
            # approach side) can be told from it
            cands = [c for c in cands if isinstance(c.effect, JointBacklash)]
    diag = diagnose(cal.q_model, cal.xy_mm, cal.approach_model, sigma_mm=cal.sigma_mm, ids=cal.ids,
                    q_val=val.q_model if len(val.ids) else None,
                    xy_val=val.xy_mm if len(val.ids) else None,
                    approach_val=val.approach_model if len(val.ids) else None,
                    candidates=cands, base_effects=tuple(base_effects), config=config)
    traced = None
    if not_flat:  # a sheet's height would be read as a joint error: not traced then
        untraced = ("the scans for effects the library lacks (time, polynomial, coupling, "
                    "elbow, approach) did not run: the sheet is not flat (sheet_height), and "
                    "a joint error would stand in for its height")
    else:
        t_of = {m.id: i / max(len(session.marks) - 1, 1) for i, m in enumerate(session.marks)}
        traced = trace(diag, cal.q_model, cal.xy_mm, cal.approach_model,
                       np.array([t_of[i] for i in cal.ids]), sigma_mm=cal.sigma_mm,
                       ids=cal.ids, q_val=val.q_model if len(val.ids) else None,
                       xy_val=val.xy_mm if len(val.ids) else None,
                       approach_val=val.approach_model if len(val.ids) else None,
                       alpha=config.selection.alpha, k_folds=config.selection.k_folds,
                       config=config)
        diag = traced.diagnosis
    diag = _print_shared(diag, cal, measurement)
    fb, ff = diag.base_fit, diag.final_fit
    has_val = len(val.ids) >= 3
    vb = rms_2d(val.xy_mm - fb.predict(val.q_model, val.approach_model)) if has_val else diag.heldout_base_mm
    vf = rms_2d(val.xy_mm - ff.predict(val.q_model, val.approach_model)) if has_val else diag.heldout_final_mm
    doc = dict(
        params=ff.params.to_json(), std=ff.base_std_json, effects=diag.effects_json(),
        residual_rms_mm=ModelRms(fb.rms_mm, ff.rms_mm),
        validation_rms_mm=ModelRms(vb, vf, diag.heldout_kind),
        base_model_params=fb.params.to_json(), base_model_std=fb.base_std_json,
        initial_guess={"method": "closed-form linear solve (generalised circle fits)",
                       "params": fb.initial.to_json()},
        identifiability={"condition_number": ff.cond, "rank": ff.rank,
                         "n_params": ff.n_params, "labels": list(ff.labels),
                         "high_correlations": [
                             {"a": a, "b": b, "r": r} for a, b, r in ff.high_correlations()],
                         "not_identifiable": list(diag.not_identifiable)},
        diagnosis={"heldout": diag.heldout_kind,
                   "accepted": [e.to_json() for e in diag.accepted],
                   "rejected": [e.to_json() for e in diag.rejected],
                   "residual_analysis": diag.analysis,
                   "thresholds": diag.thresholds},
        notes=list(ff.notes),
        residual_scale=ff.residual_scale,
        covariance=covariance_json(ff.labels, ff.cov),
        replication=_replication(ff, cal, val, measurement, config))
    if traced is not None:
        doc["diagnosis"]["discovery"] = traced.report
        if traced.drift is not None:
            doc["effects"].append(traced.drift)
    else:   # said, and read by the verdict (diagnose/verdict.judge)
        doc["diagnosis"]["discovery"] = {"skipped": untraced}
        doc["notes"].append(untraced)
    res_cal = ff.residuals_mm
    res_val = val.xy_mm - ff.predict(val.q_model, val.approach_model)
    if not_flat:
        doc["notes"].append("sheet_affine not tried: the sheet is not flat (sheet_height); "
                            "its smooth residual is the paper's height"
                            + ("" if len(cands) > 2 else "; joint_scale and joint_cyclic "
                               "not tried either: marks not measured against a printed "
                               "grid cannot tell their smooth signature from it"))
    if session.sheet is not None:
        sm = smooth_residual(np.concatenate([cal.xy_mm, val.xy_mm]),
                             np.concatenate([res_cal, res_val]), session.sheet.extent_mm,
                             config=config.smooth_residual, cause=_smooth_cause(measurement))
        if sm is not None:
            ex = next((e for e in doc["effects"] if e["name"] == "unexplained"), None)
            if ex is None:
                doc["effects"].append({"name": "unexplained", **sm})
            else:
                ex["seen"] = list(ex.get("seen", [])) + sm["seen"]
                ex.update({k: v for k, v in sm.items() if k != "seen"})
    residual_all = {i: r for i, r in zip(cal.ids, res_cal)}
    residual_all.update({i: r for i, r in zip(val.ids, res_val)})
    residual_base = {i: r for i, r in zip(cal.ids, fb.residuals_mm)}
    residual_base.update({i: r for i, r in zip(
        val.ids, val.xy_mm - fb.predict(val.q_model, val.approach_model))})
    outliers = [i for i, k in zip(cal.ids, ff.inliers) if not k]
    if outliers:
        doc["outliers"] = outliers
    # circle fits, where the plan has paper-style groups (the tool-less model)
    pm = paper_method(cal.q_deg, cal.xy_mm) if not base_effects else None
    if pm:
        doc["circles"] = {"base": pm.circle_base.to_json(), "elbow": pm.circle_elbow.to_json()}
    return _Fitted(doc, ff.model, residual_all, residual_base, diagnosis=diag)


def _replication(ff: Fit, cal: MarkData, val: MarkData, measurement,
                 config: EstimatorConfig) -> dict:
    """calibration.json ``replication``: the final model refitted on two halves of its
    fitted marks and compared (:func:`vision_cal.diagnose.replicate.replicate`), at the
    validation marks' commands when there are three or more."""
    keep = np.asarray(ff.inliers, bool)
    nv = len(val.ids)
    return replicate(
        ff.model, cal.q_model[keep], cal.xy_mm[keep], cal.approach_model[keep],
        None if cal.sigma_mm is None else cal.sigma_mm[keep],
        residual_scale=ff.residual_scale,
        check_q=val.q_model if nv >= 3 else None,
        check_approach=val.approach_model if nv >= 3 else None,
        check_label=f"the {nv} validation marks' commands",
        shared_cov_mm2=print_field_cov(None if measurement is None
                                       else measurement.print_summary, cal.xy_mm[keep]),
        config=config)
def _smooth_cause(measurement) -> str:
    """What a smooth residual is named for: the print between the markers where the sheet's
    print was measured and the marks are against its markers, else a sheet not flat."""
    pr = (None if measurement is None else measurement.print_summary) or {}
    return PRINT_BETWEEN if pr.get("applied") else NOT_FLAT


def _print_shared(diag: Diagnosis, cal: MarkData, measurement) -> Diagnosis:
    """The diagnosis with its fits' parameter covariance grown by the print's correlated
    part (measurement.json ``print`` ``field``): the as-printed layout's uncertainty moves
    every mark through its photo's mapping together, which the parameters take up (a
    0.02 mm shear of the layout turned the base 0.03 mm, 7 std, and the link 4 std, the
    residual 0.91 times its floor). Unchanged without a field."""
    C = print_field_cov(None if measurement is None else measurement.print_summary,
                        cal.xy_mm)
    if C is None:
        return diag
    fits = {}
    for name in ("base_fit", "final_fit"):
        f = getattr(diag, name)
        if len(f.inliers) == len(cal.ids):
            fits[name] = f.with_shared_error(cal.q_model, cal.approach_model, C, cal.sigma_mm)
    return replace(diag, **fits)


def document(session: Session, data: MarkData, missing: list[str],
             measurement: Measurement | None, fitted: _Fitted, *, method: str,
             config: EstimatorConfig = DEFAULT, truth: bool = False,
             bars_mm=None) -> CalibrationResult:
    """The one :class:`CalibrationResult` of a run: the fit's blocks, per-photo checks, the
    model the OLP had, the lens and the sheet height found by measurement, every mark with
    its residuals, images, targets, still cameras, the paper's scale (``bars_mm``: the
    printed bars as measured, over the sheet's), and the verdict judged on all of it."""
    blk = dict(fitted.blocks)
    effects = list(blk.pop("effects"))
    replication = blk.pop("replication", None)
    extra = {} if replication is None else {"replication": replication}
    diagnosis = blk.pop("diagnosis", None)
    notes = blk.pop("notes", None)
    if measurement is not None:
        notes = list(notes or [])
    if measurement is not None and fitted.diagnosis is not None:
        photos = per_photo_offsets(measurement, fitted.diagnosis.final_fit.model,
                                   dict(zip(data.ids, data.q_model)),
                                   dict(zip(data.ids, data.approach_model)),
                                   config=config.per_photo_offsets)
        diagnosis = {**diagnosis, "per_photo_offsets": photos}
        flagged = [p["file"] for p in photos if p["flagged"]]
        if flagged:
            notes.append("photos whose marks are shifted together beyond the noise "
                         "(a bad sheet mapping?): " + ", ".join(flagged))
    if measurement is not None and measurement.lens is not None and measurement.lens.kept:
        effects.insert(0, measurement.lens.to_effect_json())
    if measurement is not None and measurement.height_map is not None:
        hm = measurement.height_map
        if hm.claimed:
            effects.append(hm.to_effect_json())
        elif hm.not_claimed:
            notes.append(f"sheet_height not claimed: {hm.not_claimed}")
        diagnosis = {**(diagnosis or {}), "sheet_height": hm.to_json()}
    marks, unreliable_notes = _marks_json(session, data, measurement, fitted)
    if measurement is not None:
        notes += unreliable_notes
    limits = session.robot.joint_limits_deg
    printer = printer_scale(session.sheet, effects, blk["params"], bars_mm=bars_mm)
    paper = paper_scale_block(session.sheet, blk["params"], blk.get("std"), printer, config)
    if paper is not None:
        extra["paper_scale"] = paper
    cameras, camera_notes = cameras_json(session, measurement, fitted.model,
                                         covariance=blk.get("covariance"), std=blk.get("std"))
    if camera_notes:
        notes = list(notes or []) + camera_notes
    result = CalibrationResult(
        method=method, config=config.to_json(), effects=tuple(effects), diagnosis=diagnosis,
        notes=None if notes is None else tuple(notes), **blk,
        **nominal_blocks(session.raw, session.robot.params.to_json()),  # the robot file
        home_deg=tuple(float(v) for v in session.robot.home_deg),  # added: where plans start
        printed_content=printed_content_json(session.sheet) or None,  # added: for plan
        joint_limits_deg=(None if limits is None  # added: plan, export
                          else [[float(v) for v in p] for p in limits]),
        noise_floor_mm=(None if data.sigma_mm is None
                        else float(np.sqrt(2 * np.mean(data.sigma_mm**2)))),
        marks=marks, missing_marks=tuple(missing) or None,
        images=tuple(measurement.images_json()) if measurement else (),
        targets=tuple(_target_errors(session, data)) or None,
        printer_scale=printer,
        cameras=cameras or None,   # added: still cameras (vision_cal/camera/fixed.py)
        sheet=sheet_identity(session.raw.get("sheet")),  # which printed sheet: design --pilot
        # added (#28): the print's deviation from its layout and its limit on the marks;
        # (#37) the fit replicated by two halves of its marks
        extra={**({"print": measurement.print_summary}
                  if measurement is not None and measurement.print_summary is not None
                  else {}), **extra})
    if truth:
        result = replace(result, truth_comparison=compare_truth(session.root / "truth.json",
                                                                result.to_json()))
    design = session.raw.get("design") if isinstance(session.raw, dict) else None
    pen = (design or {}).get("pen_down_mm") if isinstance(design, dict) else None
    result = replace(result, valid_for=valid_for_block(
        result.to_json(), pen_down_mm=pen if isinstance(pen, (int, float)) else None))
    doc = _judged(result, session).to_json()
    add_to_calibration(doc, session)   # what the report draws: it reads only the files
    # the values exactly as written (NaN as null, numpy as Python): what is read back
    return CalibrationResult.from_json(as_json(doc))


def _judged(result: CalibrationResult, session: Session) -> CalibrationResult:
    """The run's verdict (one owner: :mod:`vision_cal.diagnose.verdict`); a residual beyond
    the noise floor is ``unexplained`` with its ratio unless an effect entry already says
    what is left."""
    v = judge(result.to_json(), repeatability_mm=session.robot.repeatability_mm,
              stage=session.design_stage)
    effects = [dict(e) for e in result.effects]
    f = v.floor
    if f is not None and f["beyond"]:
        ex = next((e for e in effects if e["name"] in ("unexplained", "drift")), None)
        line = v.floor_line
        if ex is None:
            effects.append({"name": "unexplained", "seen": [line],
                            "residual_over_floor": f["residual_over_floor"]})
        else:
            ex["residual_over_floor"] = f["residual_over_floor"]
            if ex["name"] == "unexplained":
                ex["seen"] = list(ex.get("seen", [])) + [line]
    return replace(result, effects=tuple(effects), verdict=v.to_json())


def _marks_json(session: Session, data: MarkData, measurement: Measurement | None,
                fitted: _Fitted) -> tuple[dict, list[str]]:
    """calibration.json's ``marks`` (every fitted mark with its residuals, then the marks
    found but not trusted) and the notes about the latter."""
    marks = {}
    repeat_of = {m.id: m.repeat_of for m in session.marks if m.repeat_of is not None}
    for i, mid in enumerate(data.ids):
        entry = {"measured_mm": data.xy_mm[i].tolist(),
                 **({"j4_deg": float(data.joint4[i, 0])} if data.joint4 is not None else {}),
                 "residual_mm": np.asarray(fitted.residual_all[mid]).tolist(),
                 "residual_base_mm": np.asarray(fitted.residual_base[mid]).tolist(),
                 "role": data.roles[i], "joints_deg": data.q_deg[i].tolist(),
                 "approach": data.approach[i].astype(int).tolist()}
        if data.sigma_mm is not None:
            entry["sigma_mm"] = float(data.sigma_mm[i])
        if mid in repeat_of:   # added: a return to another mark's pose (repeatability)
            entry["repeat_of"] = repeat_of[mid]
        if measurement is not None and mid in measurement.marks:  # added field
            entry["n_photos"] = int(measurement.marks[mid].n_photos)
            entry.update(measurement.mark_json(mid))
        marks[mid] = entry
    if measurement is None:
        return marks, []
    return marks, _unreliable_marks(marks, session, measurement)


def _unreliable_marks(marks: dict, session: Session, measurement: Measurement) -> list[str]:
    """Marks found but not trusted (docs/format.md, "Marks that could not be trusted"): an
    entry with ``status`` "unreliable" and the ``reason``, no residual (not fitted), added
    to ``marks``; returns the notes: the measurement's finding about the sheet's grid
    declaration (measure/grid_declaration.py) and one naming the unreliable marks."""
    notes = [w for w in measurement.warnings if w.startswith("sheet.grid.origin_mm")]
    bad = []
    for m in session.marks:
        mm = measurement.marks.get(m.id)
        if mm is None or mm.status == "ok" or m.id in marks:
            continue
        marks[m.id] = {"measured_mm": np.asarray(mm.xy_mm, float).tolist(),
                       "status": mm.status, "reason": mm.reason, "role": m.role,
                       "joints_deg": [float(v) for v in m.joints_deg],
                       "n_photos": int(mm.n_photos), **measurement.mark_json(m.id)}
        bad.append(f"{m.id} ({mm.reason})")
    if bad:
        notes.append(f"{len(bad)} mark(s) left out of the fit as unreliable: "
                     + "; ".join(bad))
    return notes


def _predict(params, d: MarkData):
    return forward(params, d.q_deg) if len(d.ids) else np.zeros((0, 2))


def _target_errors(session: Session, data: MarkData) -> list[dict]:
    """Absolute error (measured minus target) of marks that carry ``target_mm``."""
    pos = dict(zip(data.ids, data.xy_mm))
    out = []
    for m in session.marks:
        if m.target_mm is not None and m.id in pos:
            err = pos[m.id] - np.asarray(m.target_mm)
            out.append({"id": m.id, "target_mm": list(m.target_mm),
                        "measured_mm": pos[m.id].tolist(), "error_mm": err.tolist(),
                        "error_norm_mm": float(np.hypot(*err))})
    return out


def compare_truth(path: Path, doc: dict) -> dict:
    """Calibrated minus true parameters (synthetic data only; read only when asked)."""
    t = read_json(path)
    tp, cp = t["params"], doc["params"]
    out = {"L1_mm": cp["L1_mm"] - tp["L1_mm"], "L2_mm": cp["L2_mm"] - tp["L2_mm"],
           "joint_zero_deg": [cp["joint_zero_deg"][k] - tp["joint_zero_deg"][k] for k in (0, 1)],
           "base_mm": [cp["base_mm"][k] - tp["base_mm"][k] for k in (0, 1)],
           "true_effects": t.get("effects", [])}
    tm = t.get("marks", {})
    errs = [np.subtract(v["measured_mm"], tm[k]) for k, v in doc["marks"].items() if k in tm]
    if errs:
        out["mark_rms_mm"] = rms_2d(np.array(errs))
    return out


def printer_scale(sheet, effects, params: dict | None = None, *,
                  bars_mm=None) -> dict | None:
    """The printer's scale from the user's measurement of the printed bars, kept apart from
    ``sheet_affine`` (added field ``printer_scale`` of calibration.json).

    ``sheet.printed.measured_bar_mm`` = [X, Y] of the ``scale_bar_length_mm`` (100 mm) bars.
    Sheet coordinates are the file's millimetres; the print is ``x`` = X / 100 and ``y`` =
    Y / 100 times them. The photos cannot see a uniform print scale (it is the same as
    longer links), so ``uniform`` = sqrt(x y) converts the calibrated lengths (L1, L2,
    base) to physical mm; the uneven part ``x / y - 1`` appears in the photos as a
    ``sheet_affine`` stretch (arm -> sheet matrix diag(1/x, 1/y)), and
    ``sheet_affine_beyond_printer`` is what a found ``sheet_affine`` leaves once the
    printer's part is taken out (paper shrink, a tilted motion plane); ``physical_mm`` the
    calibrated link lengths times ``uniform``. None when the bars were not measured.
    ``bars_mm``: the bars as measured given to the run (``calibrate --bars-mm``), over the
    sheet's; ``source`` says which.
    """
    printed = (sheet.printed if sheet is not None else None) or {}
    mb = printed.get("measured_bar_mm") if bars_mm is None else bars_mm
    if mb is None:
        return None
    bar = float(printed.get("scale_bar_length_mm", 100.0))
    sx, sy = float(mb[0]) / bar, float(mb[1]) / bar
    out = {"x": sx, "y": sy, "uniform": float(np.sqrt(sx * sy)), "uneven": sx / sy - 1.0,
           "measured_bar_mm": [float(mb[0]), float(mb[1])], "bar_mm": bar,
           "source": ("sheet.printed.measured_bar_mm" if bars_mm is None else "--bars-mm")}
    if params:
        out["physical_mm"] = {k: float(params[k]) * out["uniform"] for k in ("L1_mm", "L2_mm")
                              if params.get(k) is not None}
    for e in effects:
        if e.get("name") == "sheet_affine" and e.get("matrix") is not None:
            m = np.asarray(e["matrix"], float)
            # found x/y stretch over the printer's (1/x)/(1/y) = y/x
            out["sheet_affine_beyond_printer"] = float(m[0, 0] * sx / (m[1, 1] * sy) - 1.0)
    return out
