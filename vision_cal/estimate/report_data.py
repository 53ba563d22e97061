"""What the report draws that needs the estimator, computed once here and written into
calibration.json (``vision_cal.report`` imports nothing of the estimator: it renders
calibration.json, measurement.json and loop.json).

:func:`with_report_data` (called by :func:`vision_cal.estimate.document.document` before
calibration.json is written): the input folder (``dataset``), each fitted mark's
residual as joint-angle errors under the base and the final model
(``residual_base_joint_deg``, ``residual_joint_deg``:
:func:`vision_cal.estimate.candidates.joint_residuals_deg` with the final parameters), and
the verdict's sentences (``verdict.text``, ``verdict.floor_line``:
:class:`vision_cal.estimate.verdict.Verdict`, the one owner). loop.json's trajectories are
the closed loop's (:func:`vision_cal.actions.loop.loop_trajectories`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.estimate.candidates import joint_residuals_deg
from vision_cal.estimate.verdict import Verdict
from vision_cal.model.kinematics import ScaraParams
from vision_cal.model.robot import RobotModel


def with_report_data(cal: CalibrationResult, session) -> CalibrationResult:
    """``cal`` with the report's fields of calibration.json (see the module docstring)."""
    marks = dict(cal.marks or {})
    for mid, extra in joint_residuals(cal).items():
        marks[mid] = {**marks[mid], **extra}
    v = cal.verdict
    if isinstance(v, dict) and "status" in v:
        verdict = Verdict.from_json(v)
        v = {**v, "text": verdict.text}
        if verdict.floor_line is not None:
            v["floor_line"] = verdict.floor_line
    return replace(cal, dataset=str(Path(session.root).resolve()), marks=marks, verdict=v)


def joint_residuals(cal: CalibrationResult) -> dict[str, dict]:
    """id -> ``residual_joint_deg`` / ``residual_base_joint_deg`` (2,) (None where the arm
    is straight: no joint error explains a residual there) of every fitted mark, when every
    mark has its joint angles; the final model's parameters turn both into joint angles."""
    m = cal.marks or {}
    ids = [i for i in m if m[i].get("status", "ok") == "ok" and "residual_mm" in m[i]]
    if not ids or not all("joints_deg" in v for v in m.values()):
        return {}
    q = np.array([m[i]["joints_deg"] for i in ids], float).reshape(-1, 2)
    s = np.array([m[i].get("approach", [1, 1]) for i in ids], float).reshape(-1, 2)
    rf = np.array([m[i]["residual_mm"] for i in ids], float).reshape(-1, 2)
    rb = np.array([m[i].get("residual_base_mm", m[i]["residual_mm"]) for i in ids],
                  float).reshape(-1, 2)
    model = RobotModel(ScaraParams.from_json(cal.params))
    db, df = joint_residuals_deg(model, q, s, rb), joint_residuals_deg(model, q, s, rf)
    return {i: {"residual_base_joint_deg": db[k].tolist(), "residual_joint_deg": df[k].tolist()}
            for k, i in enumerate(ids)}
