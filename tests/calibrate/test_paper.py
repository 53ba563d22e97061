"""The seed paper reproduced to its printed precision (Tables 2 and 3)."""

import numpy as np
import pytest

from tests.conftest import PAPER_Q, PAPER_XY
from vision_cal.calibrate.paper import paper_method
from vision_cal.errors import CalibrationError
from vision_cal.kinematics import ScaraParams, forward, inverse


def printed(value, paper, digits=1):
    """Agreement to the paper's printed precision: within half its last digit."""
    return np.all(np.abs(np.asarray(value) - np.asarray(paper)) <= 0.5 * 10.0**-digits + 1e-3)


@pytest.fixture(scope="module")
def result():
    return paper_method(PAPER_Q, PAPER_XY)


def test_circles_match_the_paper(result):
    assert printed(result.circle_base.center_mm, [-424.3, -230.4])
    assert printed(result.circle_base.radius_mm, 602.4)
    assert printed(result.circle_elbow.center_mm, [-80.6, -245.8])
    assert printed(result.circle_elbow.radius_mm, 259.9)


def test_table2(result):
    p = result.params
    assert printed(p.L1_mm, 344.1) and printed(p.L2_mm, 259.9)
    # the paper's a and b are |z1| and |z2|
    assert printed(p.z1_deg, -2.6) and printed(p.z2_deg, -8.1)


def test_table3_sheet_origin(result):
    p = result.params
    lengths_only = ScaraParams(p.L1_mm, p.L2_mm, 0.0, 0.0, p.base_x_mm, p.base_y_mm)
    q = inverse(lengths_only, [[0.0, 0.0]], elbow=1)
    landed = forward(p, q)[0]
    assert printed(landed, [43.4, -34.6])  # the paper measured (43.5, -34.7)
    q = inverse(p, [[0.0, 0.0]], elbow=1)
    assert printed(forward(p, q)[0], [0.0, 0.0])  # the paper measured (-0.2, 0.0)


def test_missing_circle_group_is_explained():
    with pytest.raises(CalibrationError, match="elbow circle"):
        paper_method(PAPER_Q[:3], PAPER_XY[:3])
