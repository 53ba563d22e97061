"""Diagnosis on kinematic synthetic data: each hidden effect named, sized; clean claims none.

(The rendered-photograph versions live in bench/diagnose.py and tests/test_end_to_end.py.)
"""

import numpy as np
import pytest

from tests.conftest import SM5, random_plan
from vision_cal.estimate.select import diagnose
from vision_cal.model.robot import JointBacklash, JointCyclic, JointScale, SheetAffine
from vision_cal.world.truth_model import TrueRobot

CASES = [
    (JointBacklash(joint=1, deg=0.05), "deg", 0.05),
    (JointBacklash(joint=2, deg=0.2), "deg", 0.2),
    (JointScale(joint=1, scale=0.001), "scale", 0.001),
    (JointScale(joint=2, scale=-0.005), "scale", -0.005),
    (JointCyclic(joint=1, harmonic=1, deg=0.1, phase_deg=40.0), "deg", 0.1),
    (JointCyclic(joint=2, harmonic=2, deg=0.03, phase_deg=-70.0), "deg", 0.03),
]


def _true(effects=()) -> TrueRobot:
    """The world's own robot (not the estimator's model), from the JSON blocks."""
    return TrueRobot.from_json(SM5.to_json(), [e.to_json() for e in effects])


def _world(effects, seed, n=38, sigma=0.01):
    rng = np.random.default_rng(seed)
    q, s = random_plan(n, rng)
    xy = _true(effects).pen_mm(q, s) + rng.normal(0, sigma, (n, 2))
    return q, s, xy


def _run(q, s, xy):
    return diagnose(q[:30], xy[:30], s[:30], q_val=q[30:], xy_val=xy[30:], approach_val=s[30:])


#: how many reported standard deviations a found value may be from the truth (two-sided
#: 6e-5 for an honest Gaussian std; a std 2x too small fails about one time in twenty)
N_STD = 4.0


def _check_base(fit):
    """Every base parameter within N_STD of its own reported std of the truth."""
    err = fit.params.vector - SM5.vector
    assert np.all(np.abs(err) < N_STD * fit.std[:6]), (err, fit.std[:6])


def _heldout_bound(sigma, n_val, n_fit, n_params):
    """Held-out RMS an honest fit reaches with noise ``sigma`` per axis: prediction error
    sqrt(2) sigma sqrt(1 + P/N) (noise of the mark plus that of the fit), its mean square
    a chi-square with 2 n_val dof: bound at its 1 - 1e-4 quantile."""
    from scipy import stats

    q = stats.chi2.ppf(1 - 1e-4, 2 * n_val) / (2 * n_val)
    return np.sqrt(2) * sigma * np.sqrt(1 + n_params / (2 * n_fit)) * np.sqrt(q)


@pytest.mark.parametrize("effect,key,size", CASES, ids=lambda c: getattr(c, "label", None))
def test_hidden_joint_effect_is_named_and_sized(effect, key, size):
    d = _run(*_world((effect,), seed=11))
    found = d.effects_json()
    assert [(e["name"], e["joint"]) for e in found] == [(effect.name, effect.joint)]
    assert abs(found[0][key] - size) < N_STD * found[0]["std"], found[0]
    _check_base(d.final_fit)
    assert d.heldout_final_mm < _heldout_bound(0.01, 8, 30, d.final_fit.n_params)
    assert d.heldout_final_mm < d.heldout_base_mm


def test_sheet_shrink_is_named_with_its_axis():
    d = _run(*_world((SheetAffine(((1.002, 0.0), (0.0, 1.0))),), seed=3))
    (e,) = d.effects_json()
    assert e["name"] == "sheet_affine" and abs(e["matrix"][0][0] - 1.002) < N_STD * e["std"]
    _check_base(d.final_fit)


@pytest.mark.parametrize("seed", range(5))
def test_clean_data_claims_nothing(seed):
    d = _run(*_world((), seed=100 + seed))
    assert d.effects_json() == []
    _check_base(d.final_fit)


def test_backlash_invisible_to_a_one_sided_plan_is_reported():
    q, s, xy = _world((JointBacklash(joint=2, deg=0.1),), seed=5)
    s[:, 1] = 1.0
    xy = _true((JointBacklash(joint=2, deg=0.1),)).pen_mm(q, s)
    d = _run(q, s, xy)
    labels = [n["label"] for n in d.not_identifiable]
    assert "joint_backlash(joint 2)" in labels
    fix = next(n["fix"] for n in d.not_identifiable if n["label"] == "joint_backlash(joint 2)")
    assert "both directions" in fix


def _fifth_harmonic_world(seed, n=60, deg=0.08, sigma=0.005):
    rng = np.random.default_rng(seed)
    q, s = random_plan(n, rng)
    link = q.copy()
    link[:, 1] += deg * np.sin(np.radians(5 * q[:, 1]))       # in no candidate
    xy = _true().pen_mm(link, s, link=True) + rng.normal(0, sigma, (n, 2))
    return q, xy, s


@pytest.mark.parametrize("seed", [8, 9, 10])
def test_unmodelled_structure_is_reported_as_unexplained(seed):
    """A fifth-harmonic error of joint 2 is in no candidate: reported with what was seen
    (joint, harmonic, size, periodogram), and never fitted as something else."""
    d = diagnose(*_fifth_harmonic_world(seed))
    assert d.accepted == ()
    assert d.unexplained is not None
    (h,) = d.unexplained["joint_harmonics"]
    assert (h["joint"], h["harmonic"]) == (2, 5)
    # noise 0.005 mm at ~300 mm from joint 2: ~1e-3 deg per mark, 60 marks: a few 1e-4 deg
    assert h["amplitude_deg"] == pytest.approx(0.08, abs=0.002)
    per = {r["harmonic"]: r for r in h["periodogram"]}
    assert per[5]["F"] > 100 * max(r["F"] for k, r in per.items() if k != 5)
    assert "joint2" in d.unexplained["seen"][0] and "harmonic 5" in d.unexplained["seen"][0]
    assert d.effects_json()[-1]["name"] == "unexplained"


def test_third_harmonic_beside_a_real_effect():
    """A real backlash is still named; the third harmonic of joint 2 beside it is not
    fitted as a cyclic or scale error but reported. (Over joint 1's 120 deg a third
    harmonic is one smooth wave that harmonics 1, 2 and a scale do explain: that is no
    structure left unexplained, so the test puts it on joint 2, which turns 280 deg.)"""
    rng = np.random.default_rng(31)
    q, s = random_plan(60, rng)
    link = _true((JointBacklash(joint=1, deg=0.1),)).link_deg(q, s)
    link[:, 1] += 0.03 * np.sin(np.radians(3 * q[:, 1]) + 0.5)
    xy = _true().pen_mm(link, s, link=True) + rng.normal(0, 0.005, (60, 2))
    d = diagnose(q, xy, s)
    assert [e.label for e in d.accepted] == ["joint_backlash(joint 1)"]
    assert d.accepted[0].effect["deg"] == pytest.approx(0.1, abs=0.005)
    (h,) = d.unexplained["joint_harmonics"]
    assert (h["joint"], h["harmonic"]) == (2, 3)
    assert h["amplitude_deg"] == pytest.approx(0.03, abs=0.002)


@pytest.mark.parametrize("seed", [20, 23, 25])
def test_local_bump_on_the_sheet_is_reported_where_it_is(seed):
    """A local bump (a wrinkle lifting 0.15 mm of the marks around one point, 80 mm wide)
    is reported with where on the sheet and how big, with its map; no global effect."""
    rng = np.random.default_rng(seed)
    q, s = random_plan(60, rng)
    xy = _true().pen_mm(q, s)
    centre = np.median(xy, axis=0)
    bump = 0.15 * np.exp(-np.sum((xy - centre) ** 2, axis=1) / (2 * 80.0**2))
    xy = xy + bump[:, None] * np.array([0.6, 0.8]) + rng.normal(0, 0.005, (60, 2))
    d = diagnose(q, xy, s)
    assert d.accepted == ()
    sheet = d.unexplained["sheet"]
    assert sheet["p_value"] < 0.005
    assert np.hypot(*(np.array(sheet["peak_mm"]) - centre)) < 2 * 80.0
    assert 0.04 < sheet["peak_size_mm"] < 0.15
    assert sheet["map"]["cells"]


def _no_paper_floor():
    import dataclasses

    from vision_cal.config import DEFAULT

    return dataclasses.replace(DEFAULT, selection=dataclasses.replace(DEFAULT.selection,
                                                                      min_sheet_affine=0.0))


def test_a_paper_scale_smaller_than_the_bars_measure_is_not_claimed():
    """Issue 28 section 4: a 0.02 % sheet scale, significant on precise marks (claimed
    without the floor), is below what the 100 mm bars can be measured to: not claimed;
    the backlash still is."""
    q, s, xy = _world((SheetAffine(((1.0, 0.0), (0.0, 1.0002))),
                       JointBacklash(joint=2, deg=0.1)), seed=1, sigma=0.003)
    args = (q[:30], xy[:30], s[:30])
    kw = dict(q_val=q[30:], xy_val=xy[30:], approach_val=s[30:])
    before = diagnose(*args, **kw, config=_no_paper_floor())
    assert "sheet_affine" in [e["name"] for e in before.effects_json()]   # the old claim
    d = diagnose(*args, **kw)
    names = [e["name"] for e in d.effects_json()]
    assert "sheet_affine" not in names and "joint_backlash" in names
    why = [r.reason for r in d.rejected if r.label.startswith("sheet_affine")]
    assert any("scale bars" in w for w in why), why


@pytest.mark.parametrize("seed", [4, 5])
def test_a_real_paper_shrink_of_a_tenth_percent_is_still_claimed(seed):
    d = _run(*_world((SheetAffine(((1.001, 0.0), (0.0, 1.0))),), seed=seed))
    (e,) = d.effects_json()
    assert e["name"] == "sheet_affine" and abs(e["matrix"][0][0] - 1.001) < N_STD * e["std"]
