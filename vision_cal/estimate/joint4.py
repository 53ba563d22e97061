"""Calibration of a dataset whose marks were drawn at several ``j4_deg`` (the pipeline's
branch for the tool and joint 4; contract "Joint 4 and the tool", docs/format.md).

Least squares: :func:`joint4_stage` fits the base model with ``tool_mm``
(:func:`vision_cal.model.tool_fit.fit_tool`), then joint 4's backlash and gear-ratio
error, each kept only when its estimate exceeds ``joint4.accept_sigma`` (config) reported std
(clean data claims nothing); :func:`vision_cal.estimate.fit.fit_lsq` then runs the usual
diagnosis (joint-1/2 effects, sheet, scans, discovery) with those held in every model, and
:func:`add_tool` writes the tool's part. The paper method (:func:`fit_joint4_paper`):
:func:`vision_cal.estimate.tool.paper_tool`, with std by linear propagation of the mark
noise (the least-squares fit's residual scale); it searches no effect (a note says so).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from vision_cal.model.tool_fit import ToolFit, fit_tool
from vision_cal.estimate.tool import paper_tool
from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.model.robot import JointBacklash, JointScale
from vision_cal.dataset.calibration_result import CalibrationResult, ModelRms
from vision_cal.dataset.covariance import covariance_json
from vision_cal.model.rms import rms_2d



def _std_json(std_base: np.ndarray, std_tool) -> dict:
    s = std_base
    return {"L1_mm": float(s[0]), "L2_mm": float(s[1]),
            "joint_zero_deg": [float(np.degrees(s[2])), float(np.degrees(s[3]))],
            "base_mm": [float(s[4]), float(s[5])], "tool_mm": [float(v) for v in std_tool]}


@dataclass(frozen=True)
class Joint4Stage:
    """The tool and the joint-4 effects kept (``effects``: ``Tool`` first), held by every
    model the diagnosis then tries for joints 1 and 2; what was tested (``to_json``)."""

    effects: tuple
    accepted: tuple      # ((label, z), ...)
    rejected: tuple
    notes: tuple
    accept_sigma: float  # the acceptance threshold used (config ``joint4.accept_sigma``)

    def to_json(self) -> dict:
        return {"accept_sigma": self.accept_sigma,
                "accepted": [{"effect": e, "z": z} for e, z in self.accepted],
                "rejected": [{"effect": e, "z": z} for e, z in self.rejected]}


def joint4_stage(cal, config: EstimatorConfig | None = None) -> Joint4Stage:
    """Least squares of the base model with ``tool_mm``, then joint 4's backlash (when
    joint 4 is approached from both sides) and gear-ratio error, each kept when its estimate
    exceeds ``config.joint4.accept_sigma`` reported std. ``cal``: marks with ``joint4``."""
    accept = (config or DEFAULT).joint4.accept_sigma
    q4, app = cal.joint4[:, 0], cal.approach_model
    base = fit_tool(cal.q_deg, q4, cal.xy_mm, approach=app, sigma_mm=cal.sigma_mm,
                    ids=cal.ids).or_raise()   # no tool fit: the run ends
    cands = [JointScale(joint=4)]
    if len(np.unique(app[:, 2])) > 1:
        cands.append(JointBacklash(joint=4))
    accepted, rejected, notes = [], [], []
    effects = (base.fit.model.tool,)
    trial = fit_tool(cal.q_deg, q4, cal.xy_mm, approach=app, effects=tuple(cands),
                     sigma_mm=cal.sigma_mm, ids=cal.ids)
    if not trial:
        notes.append(f"joint-4 effects not identifiable from these marks: {trial.reason}")
    for e in trial.joint4_effects if trial else ():
        z = float(np.max(np.abs(e.theta) / trial.effect_std(e)))
        (accepted if z > accept else rejected).append((e.label, z))
        if z > accept:
            effects += (type(e)(joint=4),)
    return Joint4Stage(effects, tuple(accepted), tuple(rejected), tuple(notes), accept)


def add_tool(result: CalibrationResult, diagnosis, stage: Joint4Stage) -> CalibrationResult:
    """A least-squares calibration whose models hold the tool (``result`` from
    :func:`vision_cal.estimate.fit.fit_lsq` with ``stage.effects``) completed:
    ``params.tool_mm``, ``std.tool_mm``, the ``tool`` block, ``base_model_params.tool_mm``
    and ``diagnosis.joint4``."""
    final = ToolFit(diagnosis.final_fit)
    base = result.base_model_params
    return replace(
        result, params={**result.params, "tool_mm": final.tool_mm.tolist()},
        std={**result.std, "tool_mm": final.tool_std_mm.tolist()}, tool=final.to_json(),
        base_model_params=None if base is None else {
            **base, "tool_mm": ToolFit(diagnosis.base_fit).tool_mm.tolist()},
        diagnosis={**(result.diagnosis or {}), "joint4": stage.to_json()},
        notes=tuple(result.notes or ()) + tuple(stage.notes) + (
            "marks at several j4_deg: tool_mm and joint-4 effects fitted first, then "
            "joint-1/2 effects selected with them",))


def fit_joint4_paper(cal, val):
    """The circle method with joint 4: (its blocks of calibration.json, model,
    residual_all, residual_base) for marks ``cal`` / ``val``
    (:class:`vision_cal.estimate.marks.MarkData` with ``joint4``)."""
    q, app = cal.q_model, cal.approach_model
    has_val = len(val.ids) > 0
    qv, appv = (val.q_model, val.approach_model) if has_val else (np.zeros((0, 3)),
                                                                   np.zeros((0, 3)))
    pt = paper_tool(cal.q_deg, cal.joint4[:, 0], cal.xy_mm)
    model = base_model = pt.model
    # the mark noise, as fit_paper takes it: the least-squares residual scale (NaN, and so
    # NaN std, when that fit cannot be made)
    lsq = fit_tool(cal.q_deg, cal.joint4[:, 0], cal.xy_mm, approach=app, robust=False)
    noise = lsq.fit.residual_scale if lsq else float("nan")
    G = np.zeros((8, cal.xy_mm.size))
    h = 1e-4
    for k in range(cal.xy_mm.size):
        dx = np.zeros(cal.xy_mm.size)
        dx[k] = h
        a = paper_tool(cal.q_deg, cal.joint4[:, 0], cal.xy_mm + dx.reshape(-1, 2))
        b = paper_tool(cal.q_deg, cal.joint4[:, 0], cal.xy_mm - dx.reshape(-1, 2))
        G[:, k] = (np.r_[a.params.vector, a.tool_mm] - np.r_[b.params.vector, b.tool_mm]) / (2 * h)
    cov = G @ G.T * noise**2
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    res_cal = cal.xy_mm - model.predict(q, app)
    res_val = val.xy_mm - model.predict(qv, appv) if has_val else np.zeros((0, 2))
    base_cal = cal.xy_mm - base_model.predict(q, app)
    base_val = val.xy_mm - base_model.predict(qv, appv) if has_val else np.zeros((0, 2))
    result = CalibrationResult(
        params={**model.params.to_json(), "tool_mm": list(pt.tool_mm)},
        std=_std_json(std[:6], std[6:]), effects=(),
        tool={**pt.to_json(), "std_mm": std[6:].tolist()},
        covariance=covariance_json(model.param_labels(), cov),
        residual_rms_mm=ModelRms(rms_2d(base_cal), rms_2d(res_cal)),
        validation_rms_mm=ModelRms(rms_2d(base_val) if has_val else None,
                                   rms_2d(res_val) if has_val else None,
                                   "validation marks" if has_val else "none"),
        notes=("marks at several j4_deg: tool_mm by the circle method on joint 4; effects "
               "are not searched by the paper method (the residual is reported as it is)",))
    residual_all = dict(zip(cal.ids, res_cal)) | dict(zip(val.ids, res_val))
    residual_base = dict(zip(cal.ids, base_cal)) | dict(zip(val.ids, base_val))
    return result, model, residual_all, residual_base
