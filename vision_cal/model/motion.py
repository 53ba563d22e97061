"""How the arm moves: the approach-sign rule, joint limits, speed limits, control period.

One owner for each of these conventions; everything else calls it.

- :func:`approach_signs` is the format's rule (``docs/conventions.md``, the contract):
  the approach of a joint is the sign of its last motion before the pen touched; where a
  session does not give it, it is the sign of the change from the previous commanded pose
  (or home), and a joint that did not move keeps its previous sign, starting at +1.
- :data:`JOINT_LIMITS_DEG`, :data:`SPEED_DEG_S`, :data:`ACCEL_DEG_S2`: the default
  (SM5-like) robot's limits, in degrees, deg/s and deg/s^2, joint 1 then joint 2;
  :data:`TRAJECTORY_DT_S`: the period at which reference trajectories are sampled
  (the seed paper's 16 ms).

The synthetic world (``vision_cal.world``) deliberately does *not*
use :func:`approach_signs`: it tracks the side each joint really arrived from through its
own motion, so a convention error here cannot cancel against the truth.
"""

from __future__ import annotations

import numpy as np

#: [[lo, hi], [lo, hi]] commanded joint range (deg) of the default robot
JOINT_LIMITS_DEG = ((-170.0, 170.0), (-150.0, 150.0))
#: [lo, hi] commanded joint-3 travel (mm, the quill's z) when the robot file does not say
#: (a 200 mm stroke downward from its top, commanded 0: Epson's SCARAs travel 100-420 mm)
JOINT3_LIMITS_MM = (-200.0, 0.0)
#: [lo, hi] commanded joint-4 range (deg) when the robot file does not say
JOINT4_LIMITS_DEG = (-360.0, 360.0)
#: peak joint speed (deg/s) of the default robot's trajectories, joint 1 then joint 2
SPEED_DEG_S = (90.0, 120.0)
#: peak joint acceleration (deg/s^2) of the default robot's trajectories
ACCEL_DEG_S2 = (300.0, 400.0)
#: sampling period (s) of reference trajectories (the seed paper's cubic splines)
TRAJECTORY_DT_S = 0.016


def approach_signs(poses_deg, home_deg=(0.0, 0.0), given=None) -> np.ndarray:
    """Approach sign (N, 2) of each joint at each of ``poses_deg`` (N, 2), visited in order
    from ``home_deg``: the sign of the change from the previous pose; a joint that did not
    move keeps its previous sign, starting at +1.

    ``given`` (optional, N entries of ``(s1, s2)`` or None): a sign stated for a pose (a
    session's ``approach`` field) replaces the rule there, and is what a joint that does
    not move afterwards keeps.
    """
    q = np.asarray(poses_deg, dtype=float).reshape(-1, 2)
    prev = np.asarray(home_deg, dtype=float).reshape(2)
    sign = np.ones(2)
    out = np.empty((len(q), 2))
    for i in range(len(q)):
        moved = np.sign(q[i] - prev)
        sign = np.where(moved != 0, moved, sign)
        if given is not None and given[i] is not None:
            sign = np.asarray(given[i], dtype=float).reshape(2)
        out[i] = sign
        prev = q[i]
    return out
