"""measurement.json ``print`` of a layout applied: what an undeclared lens leaves between the
markers is carried beyond the solve's own figure (issue 37, world2)."""

from dataclasses import replace

import numpy as np
import pytest

from vision_cal.config import DEFAULT
from vision_cal.estimate.verdict import _print_part
from vision_cal.measure.asprinted import AsPrinted
from vision_cal.measure.print_stage import print_stage


def _as_printed(lens_free: bool) -> AsPrinted:
    """Two 24 mm markers, every corner released and known to 0.02 mm per axis (unresolved
    0.028 mm, 2-D), the marks between them to ``interior_mm`` 0.03 mm by the solve."""
    dec = np.array([[[-100, 24], [-76, 24], [-76, 0], [-100, 0]],
                    [[76, 24], [100, 24], [100, 0], [76, 0]]], float)
    return AsPrinted(np.array([1, 2]), dec, dec + 0.2, np.full((2, 4, 2), 0.02),
                     np.ones((2, 4), bool), np.eye(3), np.zeros(5), (2400, 1800), lens_free,
                     ("a.jpg",), (0.7,), (0.05,), 6, interior_read=0.03,
                     field_read={"basis": "homography", "centre_mm": [0, 0], "scale_mm": 100.0,
                                 "cov_mm2": np.eye(8).tolist()},
                     replication={"status": "agree", "chi2_dof": 0.5})


def test_an_undeclared_lens_carries_more_than_its_interior_figure():
    """The world2 worlds: with the lens undeclared the marks were 1.2-2.4 times (median 1.95)
    what the solve stated between the markers off, the same in both halves (they agreed,
    chi2/dof 0.3-0.7), and the expected target error covered 7 of 10 seeds. The undeclared
    lens's interior figure is carried times ``lens_free_interior_factor`` (the limit, the
    marks' sigma); a declared lens keeps the solve's own figure."""
    f = DEFAULT.as_printed.lens_free_interior_factor
    assert f > 1.0
    free = print_stage(None, [], _as_printed(True), DEFAULT)
    held = print_stage(None, [], _as_printed(False), DEFAULT)
    assert held["limit_mm"] == pytest.approx(max(0.02 * 2**0.5, 0.03))
    assert free["limit_mm"] == pytest.approx(f * 0.03)
    assert free["sigma_mm"] == pytest.approx(f * 0.03 / 2**0.5)
    assert free["lens_free"] and free["interior_factor"] == f and "lens_free" not in held
    # the marks' shared error (the field) grows as the limit did; a declared lens's is kept
    grew = (f * 0.03 / held["limit_mm"]) ** 2
    assert np.allclose(free["field"]["cov_mm2"], grew * np.eye(8))
    assert np.allclose(held["field"]["cov_mm2"], np.eye(8))
    # the verdict carries it into the expected target error (the print's part per axis)
    assert _print_part(free, lambda *a: None, DEFAULT, None) == pytest.approx(
        f * 0.03 / 2**0.5)
    # a halves' scatter beyond what they state scales it again
    wide = print_stage(None, [], replace(_as_printed(True), replication={
        "status": "agree", "chi2_dof": 4.0}), DEFAULT)
    assert wide["limit_mm"] == pytest.approx(2.0 * f * 0.03)
