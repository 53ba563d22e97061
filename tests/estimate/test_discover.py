"""Scans along every axis and discovery of the effect the library lacks (kinematic data:
the world's own robot draws the marks, the estimator never sees its code; rendering each
case would take minutes, the rendered check is bench/diagnose.py --render's)."""

import jsonschema
import numpy as np
import pytest

from tests.conftest import SM5, random_plan
from vision_cal.dataset.io import atomic_write_json
from vision_cal.estimate.discover import axis_scans, trace
from vision_cal.estimate.select import diagnose
from vision_cal.model.motion import approach_signs
from vision_cal.actions.pipeline import calibrate_dataset
from vision_cal.plan.compensate import plan_targets
from vision_cal.world.truth_model import TrueRobot
from vision_cal.schema import validate

N, SIGMA, MEAS = 46, 0.01, 0.003      # marks, robot noise per axis, measurer's std
N_STD = 4.0


def _world(effects, seed, n=N):
    rng = np.random.default_rng(seed)
    q, s = random_plan(n, rng)
    t = np.linspace(0, 1, n)
    truth = TrueRobot.from_json(SM5.to_json(), effects)
    xy = truth.pen_mm(q, s, t=t) + rng.normal(0, SIGMA, (n, 2))
    return truth, q, s, t, xy


def _traced(effects, seed):
    truth, q, s, t, xy = _world(effects, seed)
    cal = np.arange(N) % 6 != 5
    val = ~cal
    sig = np.full(N, np.hypot(MEAS, SIGMA))
    d = diagnose(q[cal], xy[cal], s[cal], sigma_mm=sig[cal], q_val=q[val], xy_val=xy[val],
                 approach_val=s[val])
    tr = trace(d, q[cal], xy[cal], s[cal], t[cal], sigma_mm=sig[cal], q_val=q[val],
               xy_val=xy[val], approach_val=s[val])
    return truth, tr


@pytest.mark.parametrize("joint,feature,coef,words", [
    (2, "q1", 0.003, "joint 2 turns 0.003 deg more per degree of joint 1"),     # coupling
    (1, "q1^2", 2e-5, "per (degree of joint 1)^2"),                            # polynomial
    (1, "q1*q2", 1e-5, "x q1*q2"),                                              # cross term
])
def test_each_new_kind_is_named_within_4_std_and_compensated(joint, feature, coef, words):
    truth, tr = _traced([{"name": "joint_terms", "joint": joint,
                          "terms": [{"feature": feature, "coef": coef}]}], seed=7)
    effects = tr.diagnosis.effects_json()
    jt = [e for e in effects if e["name"] == "joint_terms"]
    assert len(jt) == 1 and jt[0]["joint"] == joint, effects
    assert [e["name"] for e in effects if e["name"] != "unexplained"] == ["joint_terms"]
    (term,) = jt[0]["terms"]
    assert term["feature"] == feature
    assert abs(term["coef"] - coef) < N_STD * term["std"], term
    assert words in jt[0]["description"]
    # the compensated plan, drawn by the true robot, lands within the predicted error
    # (the held-out RMS, which also holds the marks' own noise)
    model = tr.diagnosis.final_fit.model
    targets = np.array([[x, y] for x in (-150.0, -50.0, 50.0) for y in (-100.0, 0.0, 100.0)])
    planned = [p for p in plan_targets(model, [str(i) for i in range(9)], targets)
               if p.status == "ok"]
    assert len(planned) >= 6
    q = np.array([p.q_deg for p in planned])
    hit = truth.pen_mm(q, np.ones_like(q))
    err = np.linalg.norm(hit - np.array([p.target_mm for p in planned]), axis=1)
    assert np.sqrt(np.mean(err**2)) < tr.diagnosis.heldout_final_mm, err


def test_a_library_effect_stays_a_library_effect():
    _, tr = _traced([{"name": "joint_scale", "joint": 2, "scale": 0.001}], seed=8)
    names = [e["name"] for e in tr.diagnosis.effects_json()]
    assert names == ["joint_scale"], names
    assert tr.drift is None


def test_clean_data_claims_nothing():
    alarms = 0
    for seed in range(200, 212):
        _, tr = _traced([], seed)
        assert tr.drift is None, seed
        assert not [e for e in tr.diagnosis.effects_json() if e["name"] != "unexplained"], seed
        alarms += tr.report["scans"]["alarm"]
    # the scans' family rate is 1 % (bench/diagnose.py --scans: 200 datasets); two alarms
    # in 12 clean datasets has a chance below 1 % at that rate
    assert alarms <= 1


def test_drift_is_reported_and_the_verdict_is_not_reliable(tmp_path):
    truth, q, s, t, xy = _world([{"name": "drift", "param": "z1_deg", "change": 0.02}], 9)
    scan = axis_scans(*_base_fit(q, xy, s), q, s, t)
    assert next(x for x in scan["scans"] if x["name"] == "time")["alarm"]
    marks = [{"id": f"m{i:02d}", "joints_deg": q[i].tolist(), "approach": s[i].astype(int).tolist(),
              "measured_mm": xy[i].tolist(), "role": "validation" if i % 6 == 5 else "calibration"}
             for i in range(N)]
    session = {"format": "vision-cal/1", "robot": {
        "L1_mm": 345.0, "L2_mm": 260.0, "joint_zero_deg": [0.0, 0.0], "base_mm": [-420.0, -230.0]},
        "pen": {"mark_diameter_mm": 1.2}, "marks": marks}
    atomic_write_json(tmp_path / "d" / "session.json", session)
    run = calibrate_dataset(tmp_path / "d", out_dir=tmp_path / "out")
    drift = [e for e in run.document["effects"] if e["name"] == "drift"]
    assert drift and "joint 1 zero" in drift[0]["along"], run.document["effects"]
    # the joint-1 zero moved 0.02 deg: the reported change within 30 % of it
    assert drift[0]["size_mm"] == pytest.approx(np.radians(0.02) * 400, rel=0.6)
    assert run.document["verdict"]["status"] == "not reliable"
    assert any("warm it up" in r for r in run.document["verdict"]["reasons"])
    # the document follows the shipped schema (drift, verdict), which refuses a bad verdict
    validate(run.document, "calibration")
    bad = dict(run.document, verdict={"status": "fine"})
    with pytest.raises(jsonschema.ValidationError):
        validate(bad, "calibration")


def _base_fit(q, xy, s):
    from vision_cal.model.lsq import Fit

    return (Fit.from_estimate(q, xy, approach=s),)


def _bumped(effects, seed, val=False, traced=True):
    """``_world`` plus a local bump of the sheet (0.15 mm, 80 mm wide, at the marks' median
    point: bench/discover_bump.py's world), diagnosed and (``traced``) traced with k-fold
    CV or, ``val``, every sixth mark held out."""
    _, q, s, t, xy = _world(effects, seed)
    centre = np.median(xy, axis=0)
    xy = xy + (0.15 * np.exp(-np.sum((xy - centre) ** 2, axis=1) / (2 * 80.0**2)))[:, None] \
        * np.array([0.6, 0.8])
    sig = np.full(N, np.hypot(MEAS, SIGMA))
    cal = np.arange(N) % 6 != 5 if val else np.ones(N, bool)
    kw = dict(q_val=q[~cal], xy_val=xy[~cal], approach_val=s[~cal]) if val else {}
    d = diagnose(q[cal], xy[cal], s[cal], sigma_mm=sig[cal], **kw)
    if not traced:
        return d, None
    return d, trace(d, q[cal], xy[cal], s[cal], t[cal], sigma_mm=sig[cal], **kw)


@pytest.mark.parametrize("seed,val", [(5, False), (7, False)])
def test_a_local_bump_is_not_claimed_as_a_library_effect(seed, val):
    """A sheet bump and no joint effect: the selection claims no library effect for it (the
    old rule claimed joint-1 backlash on seed 5, whose map was clean only after it, and
    joint-1 cyclic harmonic 2 on seed 7, asked for away from the bump by its tails and not
    significant on every mark), and the bump stays reported where it is."""
    d, _ = _bumped([], seed, val, traced=False)
    assert d.accepted == (), [a.label for a in d.accepted]
    assert d.unexplained["sheet"]["p_value"] < 0.005
    assert d.unexplained["sheet"]["excluded_marks"] >= 1


def test_a_real_library_effect_beside_a_bump_is_still_found():
    """A real joint-1 cyclic term (harmonic 1, 0.03 deg) beside the bump, on a seed where
    every mark picks joint-1 scale instead (the bump pulls it): found away from the bump,
    confirmed on every mark, and sized within 4 std; a joint-2 backlash of 0.08 deg beside
    the bump (seed 5, with the old rule's false backlash of joint 1) found and sized."""
    cyc = [{"name": "joint_cyclic", "joint": 1, "harmonic": 1, "deg": 0.03, "phase_deg": 30.0}]
    d, _ = _bumped(cyc, 0, traced=False)
    assert [a.label for a in d.accepted] == ["joint_cyclic(joint 1, harmonic 1)"]
    (c,) = [e for e in d.effects_json() if e["name"] == "joint_cyclic"]
    assert abs(c["deg"] - 0.03) < N_STD * c["std"], c
    d, _ = _bumped([{"name": "joint_backlash", "joint": 2, "deg": 0.08}], 5, traced=False)
    assert [a.label for a in d.accepted] == ["joint_backlash(joint 2)"]
    (b,) = [e for e in d.effects_json() if e["name"] == "joint_backlash"]
    assert abs(b["deg"] - 0.08) < N_STD * b["std"], b


@pytest.mark.parametrize("seed,val", [(20, False), (25, False), (24, True)])
def test_a_local_bump_is_not_claimed_as_a_joint_term(seed, val):
    """A sheet bump and no joint effect: the marks around it share a residual, so the
    dictionary is searched away from them (or, seed 24 with validation marks, too few marks
    away from it, on every mark: q1*q2 is found there but leaves the bump behind, sheet map
    p = 0.001 after it); no joint term is added (the old rule, searching every mark, added
    joint 1's cos(q2) on seed 20, q1*q2 on seeds 25 and 24) and the bump stays reported as
    unexplained."""
    d, tr = _bumped([], seed, val)
    assert d.accepted == ()                             # the selection claims nothing either
    names = [e["name"] for e in tr.diagnosis.effects_json()]
    assert "joint_terms" not in names, tr.report["decision"]
    assert tr.report["away_from_local"]["excluded_marks"] >= 1
    assert tr.diagnosis.unexplained["sheet"]["p_value"] < 0.005


def test_a_real_joint_term_beside_a_bump_is_still_found():
    """The same bump beside a real joint-1 term cos(q2) of 0.02 deg (0.1 mm at the pen): the
    term is found away from the bump, and sized to 20 % (the reported fit holds every mark,
    the bump's too, which pull it by more than its std: 0.0173 +- 0.0006 deg on this seed)."""
    eff = [{"name": "joint_terms", "joint": 1, "terms": [{"feature": "cos(q2)",
                                                           "coef": 0.02}]}]
    _, tr = _bumped(eff, 20)
    (jt,) = [e for e in tr.diagnosis.effects_json() if e["name"] == "joint_terms"]
    term = {t["feature"]: t for t in jt["terms"]}["cos(q2)"]
    assert jt["joint"] == 1
    assert abs(term["coef"] - 0.02) < 0.2 * 0.02, term


def test_a_coupling_shared_over_most_of_the_sheet_is_still_found():
    """A joint-space effect makes neighbouring marks share a residual too: 20 marks and a
    coupling of joint 2 with q1 (0.004 deg per deg), whose shared residual covers most of the
    sheet (14 of 20 marks near its peak: too few away to search on). The search runs on every
    mark and the coupling is claimed because it leaves no shared residual behind (a bump
    stays behind: seed 24 above); the rule that searched only away from it claimed nothing
    (the rendered coupling of test_discover_rendered.py, seed 31, alike)."""
    n, coef = 20, 0.004
    _, q, s, t, xy = _world([{"name": "joint_terms", "joint": 2,
                              "terms": [{"feature": "q1", "coef": coef}]}], 4, n=n)
    sig = np.full(n, np.hypot(MEAS, SIGMA))
    tr = trace(diagnose(q, xy, s, sigma_mm=sig), q, xy, s, t, sigma_mm=sig)
    away = tr.report["away_from_local"]
    assert away["excluded_marks"] > n // 2
    assert away["p_value_after"] >= 0.005
    (jt,) = [e for e in tr.diagnosis.effects_json() if e["name"] == "joint_terms"]
    (term,) = jt["terms"]
    assert (jt["joint"], term["feature"]) == (2, "q1"), tr.report["decision"]
    assert abs(term["coef"] - coef) < N_STD * term["std"], term


def _swept(seed, n_q1=6, n_q2=7):
    """Marks drawn on a serpentine over joint 1 (drawing time follows the place on the
    sheet), measured through a print 0.15 mm RMS off its layout (a bow that turns along x
    with two waves: a smooth function of where the mark lies, the same for every photo of
    one fixed camera), a 0.1 deg joint-2 backlash, 0.01 mm noise; every sixth mark held
    out."""
    rng = np.random.default_rng(seed)
    q = []
    for i, q1 in enumerate(np.linspace(-30, 30, n_q1)):
        q2s = np.linspace(40, 130, n_q2)
        q += [[q1, q2] for q2 in (q2s if i % 2 == 0 else q2s[::-1])]
    q = np.array(q) + rng.normal(0, 0.3, (len(q), 2))
    s = approach_signs(q, (0, 90))
    t = np.linspace(0, 1, len(q))
    truth = TrueRobot.from_json(SM5.to_json(), [{"name": "joint_backlash", "joint": 2,
                                                 "deg": 0.1}])
    xy = truth.pen_mm(q, s, t=t)
    c = xy - xy.mean(axis=0)
    ph = rng.uniform(0, 2 * np.pi, 4)
    f = np.column_stack([np.sin(2 * np.pi * c[:, 1] / 260 + ph[0])
                         + 0.6 * np.cos(2 * np.pi * c[:, 0] / 330 + ph[1]),
                         np.cos(2 * np.pi * c[:, 0] / 280 + ph[2])
                         + 0.6 * np.sin(2 * np.pi * c[:, 1] / 310 + ph[3])])
    u = c / 200.0
    f = 0.3 * f + np.column_stack([-u[:, 0] * u[:, 1], u[:, 0] ** 2])
    f *= 0.15 / np.sqrt(np.mean(np.sum(f**2, axis=1)))
    xy = xy + f + rng.normal(0, 0.01, xy.shape)
    cal = np.arange(len(q)) % 6 != 5
    return q, s, t, xy, cal


@pytest.mark.parametrize("seed", [0, 7])
def test_a_print_along_the_drawing_order_is_not_drift(seed):
    """Issue 37: the print's displacement is a function of where a mark lies, drift one of
    when it was drawn; with the marks drawn across the sheet in order, time columns fit the
    print too (both seeds claimed a link-2 drift before: "the robot changed while drawing:
    warm it up"). Drift is claimed only when time explains the residual beyond a smooth map
    of the sheet; here it does not, and the time scan says the place explains it as well."""
    q, s, t, xy, cal = _swept(seed)
    val = ~cal
    sig = np.full(len(q), 0.012)
    kw = dict(q_val=q[val], xy_val=xy[val], approach_val=s[val])
    tr = trace(diagnose(q[cal], xy[cal], s[cal], sigma_mm=sig[cal], **kw), q[cal], xy[cal],
               s[cal], t[cal], sigma_mm=sig[cal], **kw)
    assert tr.drift is None, tr.report
    vs = tr.report["drift_vs_sheet"]
    assert not vs["claimed"] and vs["p_value"] >= tr.report["alpha"], vs
    assert "drift" not in tr.report["selected"]
