"""Calibration plans: which poses the robot marks, in which order, from which side.

``PlannedMark.via_deg`` are overshoot via points the arm passes just before the mark, so
that each joint arrives from the side ``approach`` says (the sign of its last motion).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PlannedMark:
    id: str
    joints_deg: tuple[float, float]
    role: str = "calibration"
    approach: tuple[int, int] = (1, 1)
    via_deg: tuple[tuple[float, float], ...] = ()

    def to_json(self) -> dict:
        """The mark's entry of session.json (what a real user knows)."""
        return {"id": self.id, "joints_deg": [float(self.joints_deg[0]), float(self.joints_deg[1])],
                "approach": [int(self.approach[0]), int(self.approach[1])], "role": self.role}


def paper_plan() -> list[PlannedMark]:
    """The seed paper's plan: zero, joint 1 at +-20 deg, joint 2 at +-60 deg.

    From home (0, 0) the joints move directly, so each approach is the sign of the move
    (a joint that did not move keeps +1).
    """
    poses = [("c00", (0.0, 0.0)), ("j1p", (20.0, 0.0)), ("j1n", (-20.0, 0.0)),
             ("j2p", (0.0, 60.0)), ("j2n", (0.0, -60.0))]
    out, prev, sign = [], np.zeros(2), np.ones(2)
    for mid, q in poses:
        moved = np.sign(np.asarray(q) - prev)
        sign = np.where(moved != 0, moved, sign)
        out.append(PlannedMark(mid, q, "calibration", (int(sign[0]), int(sign[1]))))
        prev = np.asarray(q)
    return out
