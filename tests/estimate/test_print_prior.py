"""The print not measured (issue 37): its smooth part moves every mark through the photo's
mapping together, so the parameters' covariance carries the printer's prior as a shared
error (``print_stage.print_shared_cov``), sized to the verdict's own number
(``uncertainty.unmeasured_print_mm``), and the verdict counts it once."""

import numpy as np
import pytest

from tests.estimate.test_verdict import _fit_doc
from vision_cal.config import DEFAULT
from vision_cal.estimate.verdict import judge
from vision_cal.measure.print_stage import print_shared_cov

EXTENT = (-297.0, -210.0, 297.0, 210.0)
ONE_PLACE = {"source": "one place", "seen_rms_mm": 0.0, "limit_mm": 0.0, "n_places": 1}


def test_the_unmeasured_print_is_a_shared_field_of_the_printers_size():
    g = np.stack(np.meshgrid(np.linspace(-297, 297, 25), np.linspace(-210, 210, 19)),
                 -1).reshape(-1, 2)
    C = print_shared_cov(ONE_PLACE, g, EXTENT, DEFAULT)
    rms = np.sqrt(np.trace(C) / len(g))
    assert rms == pytest.approx(DEFAULT.uncertainty.unmeasured_print_mm, rel=0.03)
    # no shift, turn or scale (the markers' frame, the paper's scale are others')
    S = np.zeros((2 * len(g), 4))
    S[0::2, 0] = S[1::2, 1] = 1
    S[0::2, 2], S[1::2, 2] = g[:, 0], g[:, 1]
    S[0::2, 3], S[1::2, 3] = -g[:, 1], g[:, 0]
    P = np.linalg.lstsq(S, C, rcond=None)[0]
    assert np.abs(S @ P).max() < 0.03 * np.abs(C).max()   # (removed on a coarser grid)
    # correlated: neighbours move together
    assert C[0, 2] > 0.5 * C[0, 0]
    # measured (a survey on its layout) or no print block: nothing of the prior
    assert print_shared_cov({"source": "survey", "applied": False,
                             "status": "not significant"}, g, EXTENT, DEFAULT) is None
    assert print_shared_cov(None, g, EXTENT, DEFAULT) is None


def test_the_print_in_the_covariance_is_counted_once():
    doc = {**_fit_doc(), "print": ONE_PLACE}
    v0 = judge(doc)
    v1 = judge({**doc, "print_in_covariance": {"at_marks_mm": 0.03}})
    t0, t1 = v0.target_std, v1.target_std
    assert t1["total_mm"] == pytest.approx(t0["total_mm"])
    assert t1["calibration_mm"] ** 2 == pytest.approx(t0["calibration_mm"] ** 2 + 0.03**2)
    assert t1["print_mm"] ** 2 == pytest.approx(t0["print_mm"] ** 2 - 0.03**2)
    assert v1.status == v0.status == "check"
