"""What the tool's tests and ``bench/tool_joint4.py`` read of the world's truth beside the
program: the tool frame's true direction."""

import numpy as np

from vision_cal.world.truth_model import TrueRobot


def tool_angle_deg(truth: TrueRobot, q_deg, approach=None) -> np.ndarray:
    """The tool frame's direction (N,) deg in the arm frame: ``phi1 + phi2 + q4_real``
    for commands ``q_deg`` (N, 3) reached from ``approach`` (N, 3)."""
    a = truth.link_deg(q_deg, approach)
    return (a[:, 0] + truth.zero_deg[0] + a[:, 1] + truth.zero_deg[1]
            + truth.joint4_deg(q_deg, approach))
