"""Calibration of a dataset whose marks were drawn at several ``j4_deg`` (the pipeline's
branch for the tool and joint 4; contract "Joint 4 and the tool", docs/format.md).

:func:`fit_joint4` returns what :class:`vision_cal.pipeline._Fitted` holds (the document's
part, the model, residuals under the final and the base model). Least squares: the base
model with ``tool_mm`` (:func:`vision_cal.calibrate.tool.fit_tool`), then joint 4's
backlash and gear-ratio error, each kept only when its estimate exceeds
``JOINT4_ACCEPT_SIGMA`` reported std (clean data claims nothing). The paper method:
:func:`vision_cal.calibrate.tool.paper_tool`, with std by linear propagation of the mark
noise (the least-squares fit's residual scale). Joint-1/2 effects are not searched on this branch (a note says so).
"""

from __future__ import annotations

import numpy as np

from vision_cal.calibrate.tool import fit_tool, joints_with_q4, paper_tool
from vision_cal.errors import CalibrationError
from vision_cal.model import JointBacklash, JointScale
from vision_cal.dataset.covariance import covariance_json
from vision_cal.rms import rms_2d

#: a joint-4 effect is reported when |estimate| > this many of its std
JOINT4_ACCEPT_SIGMA = 4.0


def _std_json(std_base: np.ndarray, std_tool) -> dict:
    s = std_base
    return {"L1_mm": float(s[0]), "L2_mm": float(s[1]),
            "joint_zero_deg": [float(np.degrees(s[2])), float(np.degrees(s[3]))],
            "base_mm": [float(s[4]), float(s[5])], "tool_mm": [float(v) for v in std_tool]}


def _q_app(d):
    q = joints_with_q4(d.q_deg, d.joint4[:, 0])
    return q, np.column_stack([d.approach, d.joint4[:, 1]])


def fit_joint4(cal, val, method: str, tool_nominal_mm=None):
    """(doc, model, residual_all, residual_base) for marks ``cal`` / ``val``
    (:class:`vision_cal.pipeline.MarkData` with ``joint4``)."""
    q, app = _q_app(cal)
    has_val = len(val.ids) > 0
    qv, appv = _q_app(val) if has_val else (np.zeros((0, 3)), np.zeros((0, 3)))
    notes = []
    if method == "paper":
        pt = paper_tool(cal.q_deg, cal.joint4[:, 0], cal.xy_mm)
        model = pt.model
        try:   # the mark noise, as fit_paper takes it: the least-squares residual scale
            noise = fit_tool(cal.q_deg, cal.joint4[:, 0], cal.xy_mm, approach=app,
                             robust=False).fit.residual_scale
        except CalibrationError:
            noise = float("nan")
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
        doc = dict(params={**model.params.to_json(), "tool_mm": list(pt.tool_mm)},
                   std=_std_json(std[:6], std[6:]), effects=[],
                   tool={**pt.to_json(), "std_mm": std[6:].tolist()},
                   covariance=covariance_json(model.param_labels(), cov))
        base_model = model
    else:
        base = fit_tool(cal.q_deg, cal.joint4[:, 0], cal.xy_mm, approach=app,
                        sigma_mm=cal.sigma_mm, ids=cal.ids)
        cands = [JointScale(joint=4)]
        if len(np.unique(app[:, 2])) > 1:
            cands.append(JointBacklash(joint=4))
        final, accepted, rejected = base, [], []
        try:
            trial = fit_tool(cal.q_deg, cal.joint4[:, 0], cal.xy_mm, approach=app,
                             effects=tuple(cands), sigma_mm=cal.sigma_mm, ids=cal.ids)
            for e in trial.joint4_effects:
                z = float(np.max(np.abs(e.theta) / trial.effect_std(e)))
                (accepted if z > JOINT4_ACCEPT_SIGMA else rejected).append((e, z))
            if accepted:
                final = fit_tool(cal.q_deg, cal.joint4[:, 0], cal.xy_mm, approach=app,
                                 effects=tuple(type(e)(joint=4) for e, _ in accepted),
                                 sigma_mm=cal.sigma_mm, ids=cal.ids)
        except CalibrationError as err:
            notes.append(f"joint-4 effects not identifiable from these marks: {err}")
        f, fb = final.fit, base.fit
        model, base_model = f.model, fb.model
        doc = dict(params={**f.params.to_json(), "tool_mm": final.tool_mm.tolist()},
                   std=_std_json(f.std[:6], final.tool_std_mm),
                   effects=[e.to_json(final.effect_std(e)) for e in final.joint4_effects],
                   tool=final.to_json(),
                   base_model_params={**fb.params.to_json(), "tool_mm": base.tool_mm.tolist()},
                   diagnosis={"joint4": {
                       "accept_sigma": JOINT4_ACCEPT_SIGMA,
                       "accepted": [{"effect": e.label, "z": z} for e, z in accepted],
                       "rejected": [{"effect": e.label, "z": z} for e, z in rejected]}},
                   identifiability={"condition_number": f.cond, "rank": f.rank,
                                    "n_params": f.n_params, "labels": list(f.labels),
                                    "high_correlations": [{"a": a, "b": b, "r": r} for a, b, r
                                                          in f.high_correlations()]},
                   residual_scale=f.residual_scale,
                   covariance=covariance_json(f.labels, f.cov))
        notes += list(f.notes)
    notes.append("marks at several j4_deg: tool_mm fitted; joint-1/2 effects are not searched "
                 "with joint 4 in this version (the residual is reported as it is)")
    res_cal = cal.xy_mm - model.predict(q, app)
    res_val = val.xy_mm - model.predict(qv, appv) if has_val else np.zeros((0, 2))
    base_cal = cal.xy_mm - base_model.predict(q, app)
    base_val = val.xy_mm - base_model.predict(qv, appv) if has_val else np.zeros((0, 2))
    doc["residual_rms_mm"] = {"base_model": rms_2d(base_cal), "final_model": rms_2d(res_cal)}
    doc["validation_rms_mm"] = {"base_model": rms_2d(base_val) if has_val else None,
                                "final_model": rms_2d(res_val) if has_val else None,
                                "kind": "validation marks" if has_val else "none"}
    doc["notes"] = notes
    residual_all = dict(zip(cal.ids, res_cal)) | dict(zip(val.ids, res_val))
    residual_base = dict(zip(cal.ids, base_cal)) | dict(zip(val.ids, base_val))
    return doc, model, residual_all, residual_base
