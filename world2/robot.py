"""The true SCARA of world2: its own forward kinematics and a joint-2 backlash.

Model (the contract's, written out again here on purpose)::

    a1 = q1 + z1,  a2 = q2 + z2 - s2 * band2 / 2      (joint 2 lags against its approach)
    pen = base + L1 (cos a1, sin a1) + L2 (cos(a1 + a2), sin(a1 + a2))

``s2`` is the sign of joint 2's last motion before the pen went down.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Scara:
    L1: float
    L2: float
    z1_deg: float
    z2_deg: float
    base: tuple[float, float]
    backlash2_deg: float = 0.0
    repeat_mm: float = 0.0            # 1-sigma per axis of where the pen really lands
    extra: dict = field(default_factory=dict)

    def pen(self, q_deg: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Pen position (N, 2) mm for commanded joints (N, 2) deg, approach signs (N, 2)."""
        q = np.atleast_2d(np.asarray(q_deg, float))
        s = np.atleast_2d(np.asarray(s, float))
        a1 = np.radians(q[:, 0] + self.z1_deg)
        a2 = np.radians(q[:, 1] + self.z2_deg - s[:, 1] * self.backlash2_deg / 2)
        x = self.base[0] + self.L1 * np.cos(a1) + self.L2 * np.cos(a1 + a2)
        y = self.base[1] + self.L1 * np.sin(a1) + self.L2 * np.sin(a1 + a2)
        return np.column_stack([x, y])

    def truth_params(self) -> dict:
        return {"L1_mm": self.L1, "L2_mm": self.L2, "joint_zero_deg": [self.z1_deg, self.z2_deg],
                "base_mm": list(self.base)}

    def truth_effects(self) -> list[dict]:
        if self.backlash2_deg == 0:
            return []
        return [{"name": "joint_backlash", "joint": 2, "deg": self.backlash2_deg}]


def approach_of(q_deg: np.ndarray, home_deg=(0.0, 0.0)) -> np.ndarray:
    """Sign of each joint's last motion before each mark (the arm goes mark to mark)."""
    s = np.ones(2)
    prev = np.asarray(home_deg, float)
    out = []
    for q in np.asarray(q_deg, float):
        moved = q != prev
        s = np.where(moved, np.sign(q - prev), s)
        out.append(s.copy())
        prev = q
    return np.array(out)


def ik(L1, L2, z1, z2, base, xy, elbow=1):
    """Commanded joints (deg) that a model puts at xy (N, 2) (no backlash)."""
    d = np.atleast_2d(xy) - np.asarray(base)
    r2 = np.sum(d**2, axis=1)
    c2 = np.clip((r2 - L1**2 - L2**2) / (2 * L1 * L2), -1, 1)
    a2 = elbow * np.arccos(c2)
    a1 = np.arctan2(d[:, 1], d[:, 0]) - np.arctan2(L2 * np.sin(a2), L1 + L2 * np.cos(a2))
    q1 = (np.degrees(a1) - z1 + 180) % 360 - 180
    q2 = np.degrees(a2) - z2
    return np.column_stack([q1, q2])
