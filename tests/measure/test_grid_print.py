"""The grid reference corrected by the print as the markers measured it (issue 37): the
printed lines are where the printer put them, not at their layout."""

import numpy as np

from vision_cal.config import DEFAULT
from vision_cal.measure.grid import GridOffset
from vision_cal.measure.grid_print import GridPrint, against_grid


def _field(p):
    """A printer's smooth displacement (mm): a feed wave along y, a bow, a skew."""
    p = np.asarray(p, float).reshape(-1, 2)
    u, v = p[:, 0] / 297.0, p[:, 1] / 210.0
    return np.column_stack([0.12 * np.sin(2 * np.pi * p[:, 1] / 230.0 + 0.7) + 0.06 * v,
                            0.08 * np.sin(2 * np.pi * p[:, 1] / 180.0 + 2.1)
                            + 0.09 * (u * u - 1 / 3)])


def _rim_markers():
    """Marker centres around an A2 sheet's rim (as `vision-cal sheet --size A2` lays them)."""
    xs = np.array([-269.0, -161.0, -54.0, 54.0, 161.0, 269.0])
    ys = np.array([-91.0, 0.0, 91.0])
    return np.vstack([np.column_stack([xs, np.full(6, -182.0)]),
                      np.column_stack([xs, np.full(6, 182.0)]),
                      np.column_stack([np.full(3, -269.0), ys]),
                      np.column_stack([np.full(3, 269.0), ys])])


def test_a_dot_against_a_displaced_grid_is_where_the_pen_put_it():
    """A pen dot at P seen through a mapping off by e; the grid lines there printed D(P) off
    their layout, seen at D + e. Against the grid corrected by the print the markers
    measured, the dot is at P within its stated std; the grid at its layout puts it at
    P - D (0.1-0.2 mm off, many std), which the correction's absence would leave."""
    rng = np.random.default_rng(5)
    c = _rim_markers()
    s = 0.02                                          # a survey's std at each marker
    gp = GridPrint.from_markers(c, _field(c) + rng.normal(0, s, c.shape), np.full(len(c), s))
    assert gp.measured
    P = rng.uniform([-230, -150], [230, 150], (40, 2))    # the pen's dots, all over the sheet
    e = rng.normal(0, 0.03, (40, 2))                       # the marker mapping's error
    z = []
    for p, ee, D in zip(P, e, _field(P)):
        go = GridOffset(D + ee, np.eye(2) * 0.004**2, np.array([50.0, 50.0]))
        xy, cov, off, oc = against_grid(p + ee, np.eye(2) * 0.003**2, go, gp)
        z.append(np.linalg.solve(np.linalg.cholesky(cov), xy - p))
        assert np.allclose(cov - oc, np.eye(2) * 0.003**2)
        raw = (p + ee) - go.d_mm                       # the grid at its layout
        assert np.allclose(raw - p, -D)
    z = np.asarray(z)
    # the misses within their stated std: chi2/dof near 1 (at most 2), none beyond 4 std
    assert np.mean(z**2) < 2.0 and np.abs(z).max() < 4.0, (np.mean(z**2), np.abs(z).max())
    # and the correction is a measurement, not just a wider std: half the variance gone
    miss = np.sqrt(np.mean(np.sum((_field(P) - gp.at(P)[0]) ** 2, axis=1)))
    assert miss < 0.75 * np.sqrt(np.mean(np.sum(_field(P) ** 2, axis=1))), miss


def test_an_unmeasured_print_is_carried_not_corrected():
    """Without a print measured, the grid stays at its layout and carries the printer's
    prior (config uncertainty.unmeasured_print_mm, 2-D RMS) in the dot's and the offset's
    covariance: an offset of the prior's size is no height."""
    gp = GridPrint.unmeasured()
    assert not gp.measured
    D, Dc = gp.at([[10.0, 20.0], [-100.0, 50.0]])
    assert np.all(D == 0)
    s2 = DEFAULT.uncertainty.unmeasured_print_mm ** 2 / 2
    assert np.allclose(Dc, s2 * np.eye(2))
    go = GridOffset(np.array([0.05, -0.04]), np.eye(2) * 1e-5, np.array([50.0, 50.0]))
    xy, cov, off, oc = against_grid(np.array([10.0, 20.0]), np.eye(2) * 1e-5, go, gp)
    assert np.allclose(off, go.d_mm) and np.allclose(oc, go.cov_mm2 + s2 * np.eye(2))
    assert float(off @ np.linalg.solve(oc, off)) < 2.0
