"""The tool offset and joint 4 by least squares (contract "Joint 4 and the tool",
docs/format.md): :func:`fit_tool` fits ``tool_mm`` (and joint-4 effects, when asked) jointly
with the base parameters and any other effect, through :class:`vision_cal.model.lsq.Fit` on
joints ``[q1, q2, q4]``; std and correlations from its covariance. Used by estimate/ (the
tool's calibration) and identify/ (the tool's first guess, fitted to the marks a first
association matched). When every mark has the same ``j4_deg`` the tool cannot be told from
link 2: :func:`folded_statement` says so, and what marks would separate it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision_cal.model.kinematics import ScaraParams
from vision_cal.model.lsq import FailedFit, Fit
from vision_cal.model.robot import Effect, JointEffect, RobotModel, Tool


def joint4_values(q4_deg, tol_deg: float = 1e-6) -> np.ndarray:
    """The distinct commanded joint-4 angles (deg), sorted."""
    q4 = np.asarray(q4_deg, dtype=float).ravel()
    return np.unique(np.round(q4 / tol_deg) * tol_deg)


def folded_statement(q4_deg, tool_nominal_mm=(0.0, 0.0)) -> dict:
    """calibration.json's ``tool`` block when every mark has the same ``j4_deg``: the
    tool is part of L2 and z2 (contract), with what would separate it."""
    v = joint4_values(q4_deg)
    return {"identified": False, "j4_deg": float(v[0]) if len(v) else 0.0,
            "tool_mm_nominal": [float(t) for t in tool_nominal_mm],
            "statement": "every mark has the same j4_deg: an off-axis pen is folded into "
                         "L2 and z2 (the calibrated L2 and z2 hold for this j4_deg only)",
            "to_separate": "draw marks at three or more j4_deg values at one joint-1/joint-2 "
                           "pose (a joint-4 circle, `vision-cal calibrate --method paper`) or "
                           "spread over the sheet (least squares)"}


@dataclass(frozen=True)
class ToolFit:
    """A least-squares fit with the tool. ``fit.model`` holds the :class:`Tool` effect."""

    fit: Fit

    def or_raise(self) -> "ToolFit":
        """This fit (the twin of :meth:`FailedFit.or_raise`)."""
        return self

    def _index(self, label: str) -> int:
        return self.fit.labels.index(label)

    @property
    def tool_mm(self) -> np.ndarray:
        """(2,) the tool in the flange frame at commanded q4 = 0, mm."""
        return np.array(self.fit.model.tool.tool_mm)

    @property
    def tool_std_mm(self) -> np.ndarray:
        """(2,) one standard deviation of ``tool_mm``."""
        return self.fit.std[[self._index("tool.x_mm"), self._index("tool.y_mm")]]

    @property
    def joint4_effects(self) -> tuple[Effect, ...]:
        return tuple(e for e in self.fit.model.effects
                     if isinstance(e, JointEffect) and e.joint == 4)

    def effect_std(self, effect: Effect) -> np.ndarray:
        """Std (k,) of an effect's theta, internal units (as ``Effect.to_json`` takes)."""
        k = self.fit.model.effects.index(effect)
        start = int(np.sum(self.fit.model.sizes[:k + 1]))
        return self.fit.std[start:start + len(effect.theta)]

    def correlations(self) -> dict:
        """Correlation of tool.x_mm and tool.y_mm with every other parameter."""
        c = self.fit.correlation
        out = {}
        for name in ("tool.x_mm", "tool.y_mm"):
            i = self._index(name)
            out[name] = {lab: float(c[i, j]) for j, lab in enumerate(self.fit.labels) if j != i}
        return out

    def to_json(self) -> dict:
        """The ``tool`` block of calibration.json (added field; ``params.tool_mm`` and
        ``std.tool_mm`` carry the same numbers)."""
        return {"identified": True, "tool_mm": self.tool_mm.tolist(),
                "std_mm": self.tool_std_mm.tolist(),
                "radius_mm": float(np.hypot(*self.tool_mm)),
                "joint4_effects": [e.to_json(self.effect_std(e)) for e in self.joint4_effects],
                "correlations": self.correlations()}


def joints_with_q4(q_deg, q4_deg) -> np.ndarray:
    """``[q1, q2, q4]`` (N, 3) from joints (N, 2) and joint 4 (N,) or a scalar."""
    q = np.asarray(q_deg, dtype=float).reshape(-1, 2)
    return np.column_stack([q, np.broadcast_to(np.asarray(q4_deg, dtype=float), (len(q),))])


def fit_tool(q_deg, q4_deg, xy_mm, *, approach=None, effects=(), sigma_mm=None, ids=None,
             robust: bool = True) -> ToolFit | FailedFit:
    """Least squares of the base model, ``tool_mm`` and ``effects`` (joint-4 ones included,
    e.g. ``JointScale(joint=4)``) from marks (N, 2) at joints (N, 2), joint 4 (N,) deg;
    ``approach`` (N, 2) or (N, 3) (joint 4's side third). A :class:`FailedFit` (falsy, with
    the reason) when the marks do not identify the tool (one ``j4_deg``) or the fit cannot
    be made: callers that branch test ``if not fit``, the others call ``.or_raise()``."""
    q4 = np.broadcast_to(np.asarray(q4_deg, dtype=float), (len(np.atleast_2d(q_deg)),))
    if len(joint4_values(q4)) < 2:
        return FailedFit(folded_statement(q4)["statement"] + "; "
                         + folded_statement(q4)["to_separate"])
    q3 = joints_with_q4(q_deg, q4)
    tool = Tool()
    if effects:   # joint-4 effects act through the tool: start them from a fitted tool
        start = fit_tool(q_deg, q4, xy_mm, approach=approach, sigma_mm=sigma_mm, ids=ids,
                         robust=robust)
        if not start:
            return start
        tool = start.fit.model.tool
    model = RobotModel(ScaraParams(1.0, 1.0), (tool,) + tuple(effects))
    fit = Fit.from_estimate(q3, xy_mm, approach=approach, model=model,
                            sigma_mm=sigma_mm, ids=ids, robust=robust)
    return ToolFit(fit) if fit else fit
