"""Marks in: the measured marks in plan order (:class:`MarkData`), from session.json's
``measured_mm`` or from the photos' measurement (:func:`collect_marks`). What every fit of
the estimator takes (:mod:`vision_cal.estimate.fit`, :mod:`vision_cal.estimate.joint4`, the
placements and the check of ``verify``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision_cal.dataset.session import Session


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


def collect_marks(session: Session, measurement=None) -> tuple[MarkData, list[str]]:
    """Marks with a position: ``measured_mm`` from the session, else from the photos, and
    the ids of the marks without one.

        data, missing = collect_marks(load_session("run/"), measurement)
    """
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
