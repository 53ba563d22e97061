"""ISO 9283 points, offsets and AP/RP: bounds from the definitions."""

from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import SM5
from vision_cal.design.iso9283 import iso_marks, iso_points_mm, offsets_mm
from vision_cal.estimate.verify import ap_rp
from vision_cal.model.robot import RobotModel


def test_points_are_the_centre_and_the_diagonals_at_10_percent():
    P = iso_points_mm((0, 0, 100, 50))
    assert P[0].tolist() == [50, 25]
    diag = np.hypot(100, 50)
    for c, p in zip([[0, 0], [100, 0], [100, 50], [0, 50]], P[1:]):
        assert np.hypot(*(p - c)) == pytest.approx(0.1 * diag)


def test_offsets_keep_the_dots_apart():
    off = offsets_mm(30, 6.0)
    d = np.hypot(*(off[:, None] - off[None]).transpose(2, 0, 1))
    assert len(off) == 30 and d[~np.eye(30, dtype=bool)].min() == pytest.approx(6.0)
    assert np.allclose(off.mean(axis=0), [0, 0], atol=3.0)


def test_ap_rp_of_a_known_scatter():
    """e ~ N(m, s^2 I): AP -> |m|, and l = |e - mean| is Rayleigh(s): mean 1.2533 s, std
    0.6551 s, so RP -> 3.218 s (bounds: 5 std of the estimates over 20000 visits)."""
    rng = np.random.default_rng(9)
    s, m = 0.01, np.array([0.03, -0.04])
    r = ap_rp(m + rng.normal(0, s, (20000, 2)))
    assert r["AP_mm"] == pytest.approx(0.05, abs=5 * s / np.sqrt(20000))
    assert r["RP_mm"] == pytest.approx(3.218 * s, rel=0.02)


def test_iso_marks_hit_their_commanded_points_through_the_model():
    """Each visit is planned with the calibrated model to its point plus its offset, from
    the +1 side of both joints, in ISO's cycle order."""
    model = RobotModel(SM5)
    marks, info = iso_marks(model, (-250, -140, 230, 150), 4)
    assert len(marks) == 20 and [m.id[4:6] for m in marks[:5]] == ["P1", "P5", "P4", "P3", "P2"]
    for m in marks:
        want = np.add(info[m.id]["point_mm"], info[m.id]["offset_mm"])
        got = model.predict(np.array([m.joints_deg]), np.array([m.approach]))[0]
        assert np.hypot(*(got - want)) < 1e-6 and m.approach == (1, 1)
