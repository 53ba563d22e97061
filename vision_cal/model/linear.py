"""Closed-form initial guess of the base model from any plan.

In complex numbers (x + iy) the base model is *linear* in three complex unknowns::

    pen = base + (L1 e^{i z1}) e^{i q1} + (L2 e^{i(z1+z2)}) e^{i(q1+q2)}

so marks at known commanded joints give ``base``, ``L1``, ``L2``, ``z1``, ``z2`` by linear
least squares. This generalises the paper's circle fits (marks sharing q2 lie on a circle
about the base, marks sharing q1 on a circle about the elbow) to any poses, and never
depends on the nominal model being close.
"""

from __future__ import annotations

import numpy as np

from vision_cal.errors import CalibrationError
from vision_cal.model.kinematics import ScaraParams


def design_matrix(q_deg: np.ndarray) -> np.ndarray:
    """Complex design matrix (N, 3): columns 1, e^{i q1}, e^{i(q1+q2)}."""
    q = np.radians(np.asarray(q_deg, dtype=float).reshape(-1, 2))
    return np.stack([np.ones(len(q)), np.exp(1j * q[:, 0]), np.exp(1j * (q[:, 0] + q[:, 1]))],
                    axis=1).astype(complex)


def explain_degeneracy(q_deg: np.ndarray) -> str | None:
    """Why marks at ``q_deg`` (N, 2) cannot fix the six base parameters, or None."""
    q = np.asarray(q_deg, dtype=float).reshape(-1, 2)
    if len(q) < 3:
        return (f"{len(q)} marks give {2 * len(q)} equations for 6 unknowns: "
                "at least 3 marks are needed")
    if np.ptp(q[:, 0]) < 1e-6:
        return (f"every mark has joint 1 at {q[0, 0]:g} deg, so the base (joint-1 axis) cannot "
                "be located: turn joint 1 between marks")
    if np.ptp(q[:, 1]) < 1e-6:
        return (f"every mark has joint 2 at {q[0, 1]:g} deg, so L1, L2 and z2 cannot be told "
                "apart: turn joint 2 between marks")
    s = np.linalg.svd(design_matrix(q), compute_uv=False)
    if s[-1] / s[0] < 1e-9:
        return "the poses do not separate the base, link 1 and link 2: spread both joints"
    return None


def linear_init(q_deg: np.ndarray, xy_mm: np.ndarray, *, weights: np.ndarray | None = None
                ) -> ScaraParams:
    """Base parameters from commanded joints (N, 2) deg and measured pen positions (N, 2) mm."""
    why = explain_degeneracy(q_deg)
    if why:
        raise CalibrationError(why)
    A = design_matrix(q_deg)
    z = np.asarray(xy_mm, dtype=float).reshape(-1, 2) @ np.array([1, 1j])
    if weights is not None:
        w = np.sqrt(np.asarray(weights, dtype=float))
        A, z = A * w[:, None], z * w
    c, *_ = np.linalg.lstsq(A, z, rcond=None)
    base, a, b = c
    z1 = np.angle(a)
    z2 = np.angle(b) - z1
    z2 = (z2 + np.pi) % (2 * np.pi) - np.pi
    return ScaraParams(float(abs(a)), float(abs(b)), float(np.degrees(z1)),
                       float(np.degrees(z2)), float(base.real), float(base.imag))
