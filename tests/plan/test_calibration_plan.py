"""informative_plan: counts, roles, clearance, spread, elbows, balanced approaches,
identifiability of backlash/scale/cyclic errors (vs the paper's 5-mark plan)."""

import numpy as np
import pytest

from vision_cal.dataset.session import Sheet, SheetMarker
from vision_cal.errors import VisionCalError
from vision_cal.model.kinematics import ScaraParams, forward
from vision_cal.model.robot import JointBacklash, JointCyclic, JointScale, RobotModel
from vision_cal.plan.calibration_plan import (PlannedMark, informative_plan, paper_plan,
                                              sheet_clearance_mm)

NOMINAL = ScaraParams(350.0, 260.0, 0.0, 0.0, -400.0, -250.0)
LIMITS = ((-150.0, 150.0), (-150.0, 150.0))


def _square(x0, y0, s=40.0):
    return np.array([[x0, y0 + s], [x0 + s, y0 + s], [x0 + s, y0], [x0, y0]])


def make_sheet(bottom_left=(-150.0, -520.0), size=(594.0, 420.0)) -> Sheet:
    """An A2 sheet in the SM5's reach with a 3 x 3 grid of 40 mm ArUco squares."""
    x0, y0 = bottom_left
    markers = []
    for fx in (0.05, 0.45, 0.85):
        for fy in (0.05, 0.45, 0.8):
            markers.append(SheetMarker(len(markers), _square(x0 + fx * size[0],
                                                             y0 + fy * size[1])))
    return Sheet("DICT_5X5_100", tuple(markers), size, bottom_left)


@pytest.fixture(scope="module")
def sheet():
    return make_sheet()


@pytest.fixture(scope="module")
def plan(sheet):
    return informative_plan(NOMINAL, sheet, rng=7)


def _arrays(plan):
    q = np.array([m.joints_deg for m in plan])
    s = np.array([m.approach for m in plan])
    role = np.array([m.role for m in plan])
    return q, s, role


def test_counts_ids_roles(plan):
    q, s, role = _arrays(plan)
    assert len(plan) == 38
    assert (role == "calibration").sum() == 30 and (role == "validation").sum() == 8
    ids = [m.id for m in plan]
    assert sorted(i for i in ids if i.startswith("c")) == [f"c{k:02d}" for k in range(30)]
    assert sorted(i for i in ids if i.startswith("v")) == [f"v{k:02d}" for k in range(8)]
    for m in plan:
        assert m.to_json()["role"] == m.role


def test_clear_of_markers_edges_and_separated(plan, sheet):
    q, _, _ = _arrays(plan)
    xy = forward(NOMINAL, q)
    assert sheet_clearance_mm(sheet, xy).min() >= 0.6 + 3.0 + 15.0
    d = np.linalg.norm(xy[:, None] - xy[None], axis=2) + np.eye(len(xy)) * 1e9
    assert d.min() >= 10.0


def test_safety_margin_absorbs_a_wrong_nominal(plan, sheet):
    """The real arm (base 5 mm, zeros 0.5 deg off) still marks clear of the markers."""
    q, _, _ = _arrays(plan)
    true = ScaraParams(350.0, 260.0, 0.5, -0.5, -395.0, -255.0)
    assert sheet_clearance_mm(sheet, forward(true, q)).min() >= 0.6 + 3.0


def test_clearance_distance_is_geometric(sheet):
    c = np.asarray(sheet.markers[4].corners_mm)      # centre marker
    right_mid = np.array([c[:, 0].max() + 7.0, c[:, 1].mean()])
    inside = c.mean(axis=0)
    got = sheet_clearance_mm(sheet, np.vstack([right_mid, inside]))
    np.testing.assert_allclose(got, [7.0, 0.0], atol=1e-9)
    x0, y0, x1, y1 = sheet.extent_mm
    assert sheet_clearance_mm(sheet, [[x0 - 1.0, (y0 + y1) / 2]])[0] == pytest.approx(-1.0)


def test_both_elbows_and_wide_joint_spread(plan):
    q, _, role = _arrays(plan)
    elbow = np.sign(np.sin(np.radians(q[:, 1] + NOMINAL.z2_deg)))
    for r in ("calibration", "validation"):
        e = elbow[role == r]
        assert (e > 0).sum() >= len(e) // 3 and (e < 0).sum() >= len(e) // 3
    lo, hi = np.array(LIMITS)[:, 0], np.array(LIMITS)[:, 1]
    assert np.all(q >= lo) and np.all(q <= hi)
    # joint 2 spans both elbows widely; joint 1 spans what the sheet allows (> 90 deg here)
    assert np.ptp(q[:, 1]) > 200.0
    assert np.ptp(q[:, 0]) > 90.0
    # spread: no large empty stretch in either joint (max gap < 1/4 of the range)
    for j in range(2):
        gaps = np.diff(np.sort(q[:, j]))
        assert gaps.max() < np.ptp(q[:, j]) / 4


def test_balanced_uncorrelated_approaches_with_overshoot_vias(plan):
    q, s, role = _arrays(plan)
    assert set(np.unique(s)) == {-1, 1}
    for r in ("calibration", "validation"):
        sr, qr = s[role == r], q[role == r]
        assert np.all(sr.sum(axis=0) == 0)            # half +1, half -1 per joint
        for j in range(2):
            for k in range(2):
                assert abs(np.corrcoef(sr[:, j], qr[:, k])[0, 1]) < 0.35
        assert abs(np.corrcoef(sr[:, 0], sr[:, 1])[0, 1]) < 0.35
    for m in plan:
        assert len(m.via_deg) == 1
        via = np.array(m.via_deg[0])
        step = np.array(m.joints_deg) - via
        np.testing.assert_array_equal(np.sign(step), m.approach)   # last motion's sign
        assert np.all(np.abs(step) > 0.5) and np.all(np.abs(step) < 10.0)
        assert np.all(np.abs(via) <= 150.0)


def test_deterministic_for_a_given_rng(sheet):
    a = informative_plan(NOMINAL, sheet, n_calibration=10, n_validation=2, rng=3,
                         n_candidates=5000)
    b = informative_plan(NOMINAL, sheet, n_calibration=10, n_validation=2, rng=3,
                         n_candidates=5000)
    c = informative_plan(NOMINAL, sheet, n_calibration=10, n_validation=2, rng=4,
                         n_candidates=5000)
    assert a == b and a != c


def test_unreachable_sheet_is_refused():
    far = make_sheet(bottom_left=(2000.0, 2000.0))
    with pytest.raises(VisionCalError, match="sheet"):
        informative_plan(NOMINAL, far, rng=0, n_candidates=2000)


def test_paper_plan_unchanged():
    p = paper_plan()
    assert [m.id for m in p] == ["c00", "j1p", "j1n", "j2p", "j2n"]
    assert all(isinstance(m, PlannedMark) and m.via_deg == () for m in p)


def _std(plan, model, noise_mm=0.05):
    q = np.array([m.joints_deg for m in plan])
    s = np.array([m.approach for m in plan])
    J = model.jacobian(q, s).reshape(-1, len(model.vector))
    sv = np.linalg.svd(J, compute_uv=False)
    if len(sv) < J.shape[1] or sv[-1] < 1e-9 * sv[0]:
        return None
    return noise_mm * np.sqrt(np.diag(np.linalg.inv(J.T @ J)))


def test_informative_plan_identifies_what_the_paper_plan_cannot(plan):
    """Backlash, gear scale and cyclic errors: the paper's 5 marks (10 equations) cannot
    fix them all; the informative plan's 30 calibration marks pin them down."""
    true = ScaraParams(344.05, 259.87, -2.57, -8.13, -424.26, -230.35)
    cal = [m for m in plan if m.role == "calibration"]
    full = RobotModel(true, (JointBacklash(1, 0.1), JointBacklash(2, 0.1), JointScale(1, 1e-3),
                             JointScale(2, 1e-3), JointCyclic(1, 1, 0.05, 30.0),
                             JointCyclic(2, 1, 0.05, 0.0)))
    assert _std(paper_plan(), full) is None
    std = _std(cal, full)
    assert std is not None
    assert np.degrees(std[6]) < 0.01 and np.degrees(std[7]) < 0.01   # backlash bands, deg
    # base + backlash + scale (10 unknowns): the paper's plan is exactly determined (no
    # redundancy at all); the informative plan measures each far better (0.05 mm noise)
    bs = RobotModel(true, full.effects[:4])
    std_paper, std = _std(paper_plan(), bs), _std(cal, bs)
    assert np.all(np.degrees(std[6:8]) < 0.005) and np.all(std[8:10] < 5e-4)
    assert np.all(std[6:10] * 3 < std_paper[6:10])
