"""The fit of one calibration: the marks (:class:`~vision_cal.estimate.marks.MarkData`) fitted
by a method, each method's blocks of calibration.json (:class:`Fitted`).

:func:`fit_marks` picks the stage: marks at several ``j4_deg`` take the tool and joint 4's
effects first (:mod:`vision_cal.estimate.joint4`), then :func:`fit_lsq` (least squares and
the diagnosis that adds what the base model lacks, :mod:`vision_cal.estimate.select`,
:mod:`vision_cal.estimate.discover`, the replication by halves) or :func:`fit_paper` (the
seed paper's circle method). A new calibration method is one more ``fit_*`` returning
:class:`Fitted`; :func:`vision_cal.estimate.document.document` makes the calibration of it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.dataset.calibration_result import CalibrationResult, ModelRms
from vision_cal.dataset.covariance import covariance_json
from vision_cal.dataset.session import Session
from vision_cal.estimate.candidates import default_candidates
from vision_cal.estimate.discover import trace
from vision_cal.estimate.joint4 import add_tool, fit_joint4_paper, joint4_stage
from vision_cal.estimate.marks import MarkData
from vision_cal.estimate.paper import PaperResult, paper_method
from vision_cal.estimate.replicate import replicate
from vision_cal.estimate.select import Diagnosis, diagnose
from vision_cal.estimate.sheet import NOT_FLAT, PRINT_BETWEEN, smooth_residual
from vision_cal.measure.print_stage import print_not_measured, print_shared_cov
from vision_cal.model.kinematics import forward
from vision_cal.model.lsq import Fit
from vision_cal.model.rms import rms_2d
from vision_cal.model.robot import JointBacklash, RobotModel, SheetAffine
from vision_cal.model.tool_fit import folded_statement


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
class Fitted:
    """What one calibration method leaves for the document: its blocks of calibration.json
    (``result``: a :class:`CalibrationResult` holding the fields the method fills), the
    final model and each mark's residual under the final and the base model."""

    result: CalibrationResult
    model: RobotModel
    residual_all: dict
    residual_base: dict
    diagnosis: Diagnosis | None = None
    paper: PaperResult | None = None


def fit_marks(session: Session, data: MarkData, measurement=None, *, method: str = "lsq",
              config: EstimatorConfig = DEFAULT) -> Fitted:
    """The calibration marks of ``data`` fitted by ``method`` (``lsq`` or ``paper``).

        fitted = fit_marks(session, collect_marks(session, measurement)[0], measurement)

    The validation marks scored: marks at several ``j4_deg`` take the tool and joint 4's
    effects first (the paper's circles for them with ``paper``); one ``j4_deg`` folds the
    tool into L2 and z2, and says so (calibration.json ``tool``)."""
    cal, val = data.select("calibration"), data.select("validation")
    if cal.joint4 is not None and len(np.unique(np.round(cal.joint4[:, 0], 6))) > 1:
        if method == "paper":
            return Fitted(*fit_joint4_paper(cal, val))
        # the tool and joint 4's effects first, then the diagnosis with them
        stage = joint4_stage(cal, config)
        fitted = fit_lsq(session, cal, val, measurement, config, stage.effects)
        return replace(fitted, result=add_tool(fitted.result, fitted.diagnosis, stage))
    fitted = (fit_paper(cal, val, config) if method == "paper"
              else fit_lsq(session, cal, val, measurement, config))
    if cal.joint4 is not None:   # one j4_deg: the tool is folded into L2 and z2
        fitted = replace(fitted, result=replace(fitted.result, tool=folded_statement(
            cal.joint4[:, 0], session.robot.tool_mm or (0.0, 0.0))))
    return fitted


def fit_paper(cal: MarkData, val: MarkData, config: EstimatorConfig = DEFAULT) -> Fitted:
    """The seed paper's circle method on the calibration marks; validation marks scored."""
    paper = paper_method(cal.q_deg, cal.xy_mm).or_raise()   # no circles: the run ends
    params = paper.params
    noise_mm = Fit.from_estimate(cal.q_deg, cal.xy_mm, approach=cal.approach, robust=False,
                                 config=config).or_raise().residual_scale  # unweighted: mm
    std, cov = _paper_std(cal.q_deg, cal.xy_mm, noise_mm)
    res_cal = cal.xy_mm - _predict(params, cal)
    res_val = val.xy_mm - _predict(params, val) if len(val.ids) else np.zeros((0, 2))
    rv = rms_2d(res_val) if len(val.ids) else None
    blocks = CalibrationResult(
        params=params.to_json(), std=std, effects=(),
        residual_rms_mm=ModelRms(rms_2d(res_cal), rms_2d(res_cal)),
        validation_rms_mm=ModelRms(rv, rv, "validation marks" if len(val.ids) else "none"),
        circles={"base": paper.circle_base.to_json(), "elbow": paper.circle_elbow.to_json()},
        covariance=covariance_json(RobotModel(params).param_labels(), cov))
    residual_all = {i: r for i, r in zip(cal.ids, res_cal)}
    residual_all.update({i: r for i, r in zip(val.ids, res_val)})
    return Fitted(blocks, RobotModel(params), residual_all, residual_all, paper=paper)


def fit_lsq(session: Session, cal: MarkData, val: MarkData, measurement,
            config: EstimatorConfig, base_effects: tuple = ()) -> Fitted:
    """Least squares, then the diagnosis that adds the effects the base model lacks
    (:func:`_diagnosed`), and its blocks of calibration.json. ``base_effects``: the tool and
    joint-4 effects every model holds (marks at several ``j4_deg``,
    :mod:`vision_cal.estimate.joint4`); the joints then carry joint 4."""
    diag, traced, cands, not_flat = _diagnosed(session, cal, val, measurement, config,
                                               base_effects)
    unshared = diag.final_fit
    diag = _print_shared(diag, cal, measurement, _extent(session), config)
    fb, ff = diag.base_fit, diag.final_fit
    has_val = len(val.ids) >= 3
    vb = rms_2d(val.xy_mm - fb.predict(val.q_model, val.approach_model)) if has_val else diag.heldout_base_mm
    vf = rms_2d(val.xy_mm - ff.predict(val.q_model, val.approach_model)) if has_val else diag.heldout_final_mm
    effects, notes = diag.effects_json(), list(ff.notes)
    diagnosis = {"heldout": diag.heldout_kind,
                 "accepted": [e.to_json() for e in diag.accepted],
                 "rejected": [e.to_json() for e in diag.rejected],
                 "residual_analysis": diag.analysis,
                 "thresholds": diag.thresholds}
    if traced is not None:
        diagnosis["discovery"] = traced.report
        if traced.drift is not None:
            effects.append(traced.drift)
    else:   # said, and read by the verdict (estimate/verdict.judge)
        diagnosis["discovery"] = {"skipped": UNTRACED}
        notes.append(UNTRACED)
    res_cal = ff.residuals_mm
    res_val = val.xy_mm - ff.predict(val.q_model, val.approach_model)
    if not_flat:
        notes.append("sheet_affine not tried: the sheet is not flat (sheet_height); "
                     "its smooth residual is the paper's height"
                     + ("" if len(cands) > 2 else "; joint_scale and joint_cyclic "
                        "not tried either: marks not measured against a printed "
                        "grid cannot tell their smooth signature from it"))
    if session.sheet is not None:
        _add_smooth_residual(effects, session, cal, val, res_cal, res_val, config,
                             measurement)
    residual_all = {i: r for i, r in zip(cal.ids, res_cal)}
    residual_all.update({i: r for i, r in zip(val.ids, res_val)})
    residual_base = {i: r for i, r in zip(cal.ids, fb.residuals_mm)}
    residual_base.update({i: r for i, r in zip(
        val.ids, val.xy_mm - fb.predict(val.q_model, val.approach_model))})
    outliers = [i for i, k in zip(cal.ids, ff.inliers) if not k]
    # circle fits, where the plan has paper-style groups (the tool-less model)
    pm = paper_method(cal.q_deg, cal.xy_mm) if not base_effects else None
    result = CalibrationResult(
        params=ff.params.to_json(), std=ff.base_std_json, effects=tuple(effects),
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
        diagnosis=diagnosis, notes=tuple(notes), residual_scale=ff.residual_scale,
        covariance=covariance_json(ff.labels, ff.cov), outliers=tuple(outliers) or None,
        circles=({"base": pm.circle_base.to_json(), "elbow": pm.circle_elbow.to_json()}
                 if pm else None),
        extra={"replication": _replication(ff, session, cal, val, measurement, config),
               **_print_in_covariance(diag, unshared, cal, measurement)})
    return Fitted(result, ff.model, residual_all, residual_base, diagnosis=diag)


#: said when the scans for unnamed effects do not run (read by the verdict)
UNTRACED = ("the scans for effects the library lacks (time, polynomial, coupling, elbow, "
            "approach) did not run: the sheet is not flat (sheet_height), and a joint error "
            "would stand in for its height")


def _diagnosed(session: Session, cal: MarkData, val: MarkData, measurement,
               config: EstimatorConfig, base_effects: tuple):
    """(the diagnosis, the discovery's trace or None, the
    candidates tried (None: every one), whether the sheet is not flat): the selection
    (:func:`vision_cal.estimate.select.diagnose`), then the scans for what the library
    lacks (:func:`vision_cal.estimate.discover.trace`) unless the sheet is not flat."""
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
    if not not_flat:  # a sheet's height would be read as a joint error: not traced then
        t_of = {m.id: i / max(len(session.marks) - 1, 1) for i, m in enumerate(session.marks)}
        traced = trace(diag, cal.q_model, cal.xy_mm, cal.approach_model,
                       np.array([t_of[i] for i in cal.ids]), sigma_mm=cal.sigma_mm,
                       ids=cal.ids, q_val=val.q_model if len(val.ids) else None,
                       xy_val=val.xy_mm if len(val.ids) else None,
                       approach_val=val.approach_model if len(val.ids) else None,
                       alpha=config.selection.alpha, k_folds=config.selection.k_folds,
                       config=config)
        diag = traced.diagnosis
    return diag, traced, cands, not_flat


def _add_smooth_residual(effects: list, session: Session, cal: MarkData, val: MarkData,
                         res_cal, res_val, config: EstimatorConfig, measurement) -> None:
    """A residual smooth over the sheet (:func:`vision_cal.estimate.sheet.smooth_residual`)
    into the ``unexplained`` entry of ``effects`` (added when there is none)."""
    sm = smooth_residual(np.concatenate([cal.xy_mm, val.xy_mm]),
                         np.concatenate([res_cal, res_val]), session.sheet.extent_mm,
                         config=config.smooth_residual, cause=_smooth_cause(measurement))
    if sm is None:
        return
    ex = next((e for e in effects if e["name"] == "unexplained"), None)
    if ex is None:
        effects.append({"name": "unexplained", **sm})
    else:
        ex["seen"] = list(ex.get("seen", [])) + sm["seen"]
        ex.update({k: v for k, v in sm.items() if k != "seen"})


def _smooth_cause(measurement) -> str:
    """What a smooth residual is named for: the print between the markers where the sheet's
    print was measured and the marks are against its markers, else a sheet not flat."""
    pr = (None if measurement is None else measurement.print_summary) or {}
    return PRINT_BETWEEN if pr.get("applied") else NOT_FLAT


def _replication(ff: Fit, session: Session, cal: MarkData, val: MarkData, measurement,
                 config: EstimatorConfig) -> dict:
    """calibration.json ``replication``: the final model refitted on two halves of its
    fitted marks and compared (:func:`vision_cal.estimate.replicate.replicate`), at the
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
        shared_cov_mm2=print_shared_cov(None if measurement is None
                                        else measurement.print_summary, cal.xy_mm[keep],
                                        _extent(session), config),
        config=config)


def _extent(session: Session):
    """The paper's extent [x0, y0, x1, y1] (mm), None without a sheet."""
    return None if session.sheet is None else session.sheet.extent_mm


def _print_shared(diag: Diagnosis, cal: MarkData, measurement, extent_mm,
                  config: EstimatorConfig) -> Diagnosis:
    """The diagnosis with its fits' parameter covariance grown by the print's correlated
    part (:func:`vision_cal.measure.print_stage.print_shared_cov`): the as-printed layout's
    uncertainty (measurement.json ``print`` ``field``) moves every mark through its photo's
    mapping together, which the parameters take up (a 0.02 mm shear of the layout turned
    the base 0.03 mm, 7 std, and the link 4 std, the residual 0.91 times its floor); so
    does the print itself where it is not measured (the printer's prior: a 0.15 mm print
    seen from one place turned joint 2's zero 0.097 deg, 11 std, issue 37). Unchanged
    without either."""
    C = print_shared_cov(None if measurement is None else measurement.print_summary,
                         cal.xy_mm, extent_mm, config)
    if C is None:
        return diag
    fits = {}
    for name in ("base_fit", "final_fit"):
        f = getattr(diag, name)
        if len(f.inliers) == len(cal.ids):
            fits[name] = f.with_shared_error(cal.q_model, cal.approach_model, C, cal.sigma_mm)
    return replace(diag, **fits)


def _print_in_covariance(diag: Diagnosis, unshared: Fit, cal: MarkData, measurement) -> dict:
    """calibration.json ``print_in_covariance`` (the print not measured: its prior carried
    in the covariance, :func:`_print_shared`): ``at_marks_mm``, the per-axis std it adds to
    where the fitted marks' commands land, RMS over them (the verdict's ``target_std`` moves
    it from the print's part to the calibration's, so that it counts once). Empty when the
    print is measured or the covariance does not hold it."""
    pr = None if measurement is None else measurement.print_summary
    ff = diag.final_fit
    if not print_not_measured(pr) or ff.cov is unshared.cov:
        return {}
    J = ff.model.jacobian(cal.q_model, cal.approach_model)          # (N, 2, P)
    d = np.einsum("nip,pq,niq->n", J, ff.cov - unshared.cov, J) / 2
    return {"print_in_covariance": {"source": "printer's prior", "at_marks_mm":
                                    float(np.sqrt(max(float(np.mean(d)), 0.0)))}}


def _predict(params, d: MarkData):
    return forward(params, d.q_deg) if len(d.ids) else np.zeros((0, 2))
