"""Shared fixtures: the seed paper's data and a synthetic kinematic world."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vision_cal.model.kinematics import ScaraParams

ROOT = Path(__file__).resolve().parents[1]
PAPER_Q = np.array([[0, 0], [20, 0], [-20, 0], [0, 60], [0, -60]], dtype=float)
PAPER_XY = np.array([[174.8, -294.0], [160.1, -83.9], [115.5, -497.9], [89.3, -49.1],
                     [4.0, -491.5]])
SM5 = ScaraParams(344.05, 259.87, -2.57, -8.13, -424.26, -230.35)


@pytest.fixture(scope="session")
def paper_folder() -> Path:
    return ROOT / "fixtures" / "paper_sm5"


def random_plan(n: int, rng, *, q1=(-80.0, 40.0), q2=(-140.0, 140.0)):
    """Commanded joints (n, 2) deg and balanced random approach signs (n, 2)."""
    q = np.column_stack([rng.uniform(*q1, n), rng.uniform(*q2, n)])
    s = rng.choice([-1.0, 1.0], (n, 2))
    return q, s
