"""Candidate effects the diagnosis may add to the base model.

Each candidate is an effect (``vision_cal.model.robot``) at zero with its own Jacobian, plus the
plan change that would make it identifiable when the plan cannot see it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision_cal.model.robot import Effect, JointBacklash, JointCyclic, JointScale, SheetAffine


@dataclass(frozen=True)
class Candidate:
    effect: Effect
    fix: str  # the plan change that makes it identifiable

    @property
    def label(self) -> str:
        return self.effect.label

    @property
    def key(self) -> str:
        """Candidates sharing a key are alternatives: at most one of them is kept."""
        e = self.effect
        if isinstance(e, SheetAffine):
            return "sheet_affine:scale" if e.dof in ("x", "y") else "sheet_affine:shear"
        if isinstance(e, JointCyclic):
            return f"{e.name}:{e.joint}:{e.harmonic}"
        return f"{e.name}:{getattr(e, 'joint', '')}"


def default_candidates() -> list[Candidate]:
    out = []
    for j in (1, 2):
        out.append(Candidate(JointBacklash(joint=j),
                             f"reach joint {j} from both directions (overshoot via points)"))
        out.append(Candidate(JointScale(joint=j),
                             f"spread joint {j} over a wider range of angles"))
        for h in (1, 2):
            out.append(Candidate(JointCyclic(joint=j, harmonic=h),
                                 f"spread joint {j} over more of its turn"))
    out.append(Candidate(SheetAffine(dof="x"), "mark over more of the sheet in both axes"))
    out.append(Candidate(SheetAffine(dof="y"), "mark over more of the sheet in both axes"))
    out.append(Candidate(SheetAffine(dof="shear"), "mark over more of the sheet in both axes"))
    return out


def joint_residuals_deg(model, q_deg, approach, residual_mm) -> np.ndarray:
    """Residuals (N, 2) expressed as joint-angle errors in degrees (2x2 solve per mark).

    A residual ``r`` at a mark is ``J_q dq`` for the joint-angle error ``dq`` that would
    explain it exactly; near the singularity (elbow straight) this is ill-conditioned and
    returns NaN.
    """
    jq = model.joint_columns(q_deg, approach)
    det = np.linalg.det(jq)
    ok = np.abs(det) > 1e-3 * np.max(np.abs(det))
    out = np.full((len(q_deg), 2), np.nan)
    out[ok] = np.linalg.solve(jq[ok], np.asarray(residual_mm)[ok][..., None])[..., 0]
    return np.degrees(out)
