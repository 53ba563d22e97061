import numpy as np
import pytest

from vision_cal.estimate.circles import Circle
from vision_cal.errors import CalibrationError


def test_three_point_circle_is_exact():
    c = Circle.from_three_points(Circle((3.0, -4.0), 10.0).predict([0.1, 1.5, 3.0]))
    assert c.center_mm == pytest.approx((3.0, -4.0)) and c.radius_mm == pytest.approx(10.0)


def test_collinear_points_refused():
    """A failure is a falsy value with the reason; ``or_raise`` ends the run with it."""
    c = Circle.from_three_points([[0, 0], [1, 1], [2, 2]])
    assert not c and "collinear" in c.reason
    with pytest.raises(CalibrationError, match="collinear"):
        c.or_raise()
    c = Circle.from_estimate([[0, 0], [1, 1]])
    assert not c and "at least 3" in c.reason
    c = Circle.from_estimate([[0, 0], [1, 1], [2, 2], [3, 3]])
    assert not c and "collinear" in c.reason
    assert Circle.from_estimate([[1, 0], [0, 1], [-1, 0], [0, -1]])   # a circle is truthy


def test_hyper_is_unbiased_on_short_arcs_where_kasa_is_not():
    """Over many noisy 40-degree arcs the mean radius error stays near zero."""
    rng = np.random.default_rng(5)
    truth = Circle((-424.3, -230.4), 602.4)
    errs, kasa = [], []
    for _ in range(600):
        a = rng.uniform(-0.35, 0.35, 12)
        p = truth.predict(a) + rng.normal(0, 1.0, (12, 2))
        errs.append(Circle.from_estimate(p, refine=False).radius_mm - 602.4)
        A = np.column_stack([p, np.ones(len(p))])
        sol, *_ = np.linalg.lstsq(A, np.sum(p**2, axis=1), rcond=None)
        kasa.append(np.sqrt(sol[2] + (sol[0] / 2) ** 2 + (sol[1] / 2) ** 2) - 602.4)
    se = np.std(errs) / np.sqrt(len(errs))
    se_kasa = np.std(kasa) / np.sqrt(len(kasa))
    assert abs(np.mean(errs)) < 3 * se
    assert np.mean(kasa) < -4 * se_kasa  # Kasa shrinks short arcs


def test_geometric_fit_covariance_is_honest():
    rng = np.random.default_rng(9)
    truth = Circle((10.0, 20.0), 260.0)
    z = []
    for _ in range(200):
        a = rng.uniform(-1.0, 1.0, 15)
        c = Circle.from_estimate(truth.predict(a) + rng.normal(0, 0.05, (15, 2)))
        z.append((c.center_mm[0] - 10.0) / c.std[0])
    assert 0.75 < np.std(z) < 1.3
    assert c.arc_span_deg < 2 * np.degrees(1.0) + 1e-9
