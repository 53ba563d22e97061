"""Diagnosis on kinematic synthetic data: each hidden effect named, sized; clean claims none.

(The rendered-photograph versions live in bench/diagnose.py and tests/test_end_to_end.py.)
"""

import numpy as np
import pytest

from tests.conftest import SM5, random_plan
from vision_cal.diagnose.select import diagnose
from vision_cal.model import JointBacklash, JointCyclic, JointScale, RobotModel, SheetAffine

CASES = [
    (JointBacklash(joint=1, deg=0.05), "deg", 0.05),
    (JointBacklash(joint=2, deg=0.2), "deg", 0.2),
    (JointScale(joint=1, scale=0.001), "scale", 0.001),
    (JointScale(joint=2, scale=-0.005), "scale", -0.005),
    (JointCyclic(joint=1, harmonic=1, deg=0.1, phase_deg=40.0), "deg", 0.1),
    (JointCyclic(joint=2, harmonic=2, deg=0.03, phase_deg=-70.0), "deg", 0.03),
]


def _world(effects, seed, n=38, sigma=0.01):
    rng = np.random.default_rng(seed)
    q, s = random_plan(n, rng)
    xy = RobotModel(SM5, effects).predict(q, s) + rng.normal(0, sigma, (n, 2))
    return q, s, xy


def _run(q, s, xy):
    return diagnose(q[:30], xy[:30], s[:30], q_val=q[30:], xy_val=xy[30:], approach_val=s[30:])


def _check_base(p):
    assert abs(p.L1_mm - SM5.L1_mm) < 0.05 and abs(p.L2_mm - SM5.L2_mm) < 0.05
    assert abs(p.z1_deg - SM5.z1_deg) < 0.01 and abs(p.z2_deg - SM5.z2_deg) < 0.01
    assert np.hypot(p.base_x_mm - SM5.base_x_mm, p.base_y_mm - SM5.base_y_mm) < 0.05


@pytest.mark.parametrize("effect,key,size", CASES, ids=lambda c: getattr(c, "label", None))
def test_hidden_joint_effect_is_named_and_sized(effect, key, size):
    d = _run(*_world((effect,), seed=11))
    found = d.effects_json()
    assert [(e["name"], e["joint"]) for e in found] == [(effect.name, effect.joint)]
    assert found[0][key] == pytest.approx(size, rel=0.2)
    _check_base(d.final_fit.params)
    assert d.heldout_final_mm < 1.5 * 0.01 * np.sqrt(2) * 1.3
    assert d.heldout_final_mm < d.heldout_base_mm


def test_sheet_shrink_is_named_with_its_axis():
    d = _run(*_world((SheetAffine(((1.002, 0.0), (0.0, 1.0))),), seed=3))
    (e,) = d.effects_json()
    assert e["name"] == "sheet_affine" and e["matrix"][0][0] == pytest.approx(1.002, abs=4e-4)
    _check_base(d.final_fit.params)


@pytest.mark.parametrize("seed", range(5))
def test_clean_data_claims_nothing(seed):
    d = _run(*_world((), seed=100 + seed))
    assert d.effects_json() == []
    _check_base(d.final_fit.params)


def test_backlash_invisible_to_a_one_sided_plan_is_reported():
    q, s, xy = _world((JointBacklash(joint=2, deg=0.1),), seed=5)
    s[:, 1] = 1.0
    xy = RobotModel(SM5, (JointBacklash(joint=2, deg=0.1),)).predict(q, s)
    d = _run(q, s, xy)
    labels = [n["label"] for n in d.not_identifiable]
    assert "joint_backlash(joint 2)" in labels
    fix = next(n["fix"] for n in d.not_identifiable if n["label"] == "joint_backlash(joint 2)")
    assert "both directions" in fix


def test_unmodelled_structure_is_reported_as_unexplained():
    """A third-harmonic error is in no candidate: it must not pass silently."""
    rng = np.random.default_rng(8)
    q, s = random_plan(60, rng)
    m = RobotModel(SM5)
    phi = q.copy()
    phi[:, 1] += 0.08 * np.sin(np.radians(5 * q[:, 1]))
    xy = m.predict(phi, s) + rng.normal(0, 0.005, (60, 2))
    d = diagnose(q, xy, s)
    assert d.unexplained is not None or d.heldout_final_mm > 2 * 0.005 * np.sqrt(2)
