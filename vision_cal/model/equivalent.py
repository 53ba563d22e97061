"""Joints of a tool-less model equivalent to a model with a tool: for code that predicts
marks with the base model only (the association of dots to marks, identify/)."""

from __future__ import annotations

import numpy as np

from vision_cal.model.kinematics import ScaraParams, forward_tool, inverse


def equivalent_joints(params: ScaraParams, tool_mm, q_deg, q4_deg,
                      solve_with: ScaraParams | None = None) -> np.ndarray:
    """Joints (N, 2) deg that put the tool-less model ``solve_with`` (default ``params``)
    where ``params`` with the tool ``tool_mm`` puts the pen at joints ``q_deg`` (N, 2) and
    joint 4 ``q4_deg`` (N,), same elbow: for code that predicts marks with the base model
    only (the association of dots to marks). NaN where the point is out of the tool-less
    model's reach (``params`` with L2 lengthened by |tool| reaches every pen position)."""
    solve_with = params if solve_with is None else solve_with
    q = np.asarray(q_deg, dtype=float).reshape(-1, 2)
    xy = forward_tool(params, q, np.asarray(q4_deg, dtype=float), tool_mm)
    out = np.full_like(q, np.nan)
    for elbow in (1, -1):
        k = np.sign(np.sin(np.radians(q[:, 1] + params.z2_deg))) == elbow
        if k.any():
            out[k] = inverse(solve_with, xy[k], elbow=elbow, on_fail="nan")
    return out
