"""vision_cal.estimate.verify.compare on kinematic data (no photos): the verdict and the moved
parameters, with bounds from the reported std and the noise put in."""

from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import SM5, random_plan
from vision_cal.errors import CalibrationError
from vision_cal.model.robot import JointBacklash, RobotModel
from vision_cal.config import DEFAULT
from vision_cal.estimate.verify import compare

MOVED_SIGMA = DEFAULT.verify.moved_sigma

NOISE_MM = 0.01                      # per axis, as the rendered photos measure
CAL_DOC = {"validation_rms_mm": {"final_model": NOISE_MM * np.sqrt(2)}}
CAL = RobotModel(SM5, (JointBacklash(2, 0.1),))


def check(true: RobotModel, seed: int, n: int = 10):
    rng = np.random.default_rng(seed)
    q, s = random_plan(n, rng)
    xy = true.predict(q, s) + rng.normal(0, NOISE_MM, (n, 2))
    ids = [f"c{i:02d}" for i in range(n)]
    return compare(CAL, CAL_DOC, ids, q, s, xy)


def moved(model: RobotModel, *, L1=0.0, z1=0.0, z2=0.0, base=(0.0, 0.0)) -> RobotModel:
    p = model.params
    from vision_cal.model.kinematics import ScaraParams

    return RobotModel(ScaraParams(p.L1_mm + L1, p.L2_mm, p.z1_deg + z1, p.z2_deg + z2,
                                  p.base_mm[0] + base[0], p.base_mm[1] + base[1]),
                      model.effects)


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_unchanged_robot_on_a_sheet_placed_elsewhere_is_still_good(seed):
    r = check(moved(CAL, z1=1.3, base=(12.0, -7.0)), seed)
    assert r.verdict == "still good", r.reasons
    assert r.changes["base_x_mm"]["sheet_placement"]
    assert abs(r.changes["base_x_mm"]["delta"] - 12.0) < 4 * r.changes["base_x_mm"]["std"]


@pytest.mark.parametrize("seed", [21, 22])
def test_a_moved_joint_2_zero_is_found_within_4_std(seed):
    r = check(moved(CAL, z2=0.04, z1=-0.5, base=(5.0, 3.0)), seed)
    assert r.verdict.startswith("re-zero joint 2: add -"), r.reasons   # the zero grew
    z2 = r.changes["z2_deg"]
    assert z2["moved"] and abs(z2["delta"] - 0.04) < 4 * z2["std"]
    assert z2["sigmas"] > MOVED_SIGMA


def test_a_changed_link_or_backlash_means_recalibrate():
    r = check(moved(CAL, L1=0.3), 31)
    assert r.verdict == "recalibrate" and r.changes["L1_mm"]["moved"], r.reasons
    # a backlash that grew is no base parameter: the errors stay after the refit
    r = check(RobotModel(SM5, (JointBacklash(2, 0.25),)), 32)
    assert r.verdict == "recalibrate", r.reasons
    assert r.rms_mm["refitted"] > r.bound_mm


def test_the_thresholds_are_the_calibrations_own():
    """The check is judged with the ``config.verify`` the calibration recorded (verify.json
    says which): a moved zero is no move where the file asks for more std."""
    r = check(moved(CAL, z2=0.04, z1=-0.5, base=(5.0, 3.0)), 21)
    lax = dict(CAL_DOC, config={"verify": {"moved_sigma": 1e6, "tolerance_factor": 1e3}})
    rng = np.random.default_rng(21)
    q, s = random_plan(10, rng)
    xy = moved(CAL, z2=0.04, z1=-0.5, base=(5.0, 3.0)).predict(q, s) + rng.normal(
        0, NOISE_MM, (10, 2))
    r2 = compare(CAL, lax, [f"c{i:02d}" for i in range(10)], q, s, xy)
    assert r.changes["z2_deg"]["moved"] and not r2.changes["z2_deg"]["moved"]
    assert r2.verdict == "still good" and r2.to_json()["thresholds"] == {
        "moved_sigma": 1e6, "tolerance_factor": 1e3}
    assert r.to_json()["thresholds"] == {"moved_sigma": MOVED_SIGMA, "tolerance_factor": 2.0}


def test_too_few_marks_is_a_calibration_error():
    with pytest.raises(CalibrationError, match="at least 5"):
        check(CAL, 1, n=4)


def test_iso9283_visits_give_ap_and_rp_from_their_own_commanded_points():
    """Visits of one point at offsets 6 mm apart, the robot unchanged: each visit's own
    commanded point is taken out, so AP is within the noise of the mean (4 std) and RP
    near its Rayleigh value 3.218 sigma, though the offsets span 18 mm."""
    from vision_cal.design.iso9283 import iso_marks

    rng = np.random.default_rng(41)
    true = moved(CAL, z1=0.4, base=(3.0, -2.0))            # a new sheet
    marks, info = iso_marks(CAL, (-250, -140, 230, 150), 30)
    q = np.array([m.joints_deg for m in marks])
    s = np.array([m.approach for m in marks], float)
    xy = true.predict(q, s) + rng.normal(0, NOISE_MM, q.shape)
    qc, sc = random_plan(10, rng)
    xyc = true.predict(qc, sc) + rng.normal(0, NOISE_MM, qc.shape)
    r = compare(CAL, CAL_DOC, [f"c{i}" for i in range(10)], qc, sc, xyc,
                iso=([m.id for m in marks], q, s, xy, [info[m.id]["point"] for m in marks]))
    assert set(r.iso9283) == {"P1", "P2", "P3", "P4", "P5"}
    for v in r.iso9283.values():
        assert v["n"] == 30
        assert v["AP_mm"] < 4 * NOISE_MM * np.sqrt(2) / np.sqrt(30) + 0.01  # + the placement fit
        assert 1.5 * NOISE_MM < v["RP_mm"] < 5.0 * NOISE_MM


def test_the_rezero_verdict_says_one_sign_and_one_action_a_line():
    """Issue 38: the verdict, its actions and verify.json say the same figure in the
    report's convention (what to add to the controller's offset: the zero grew by +0.04,
    so add -0.04), each action on its own console line; the results' folder is named as
    the user named the photos' folder (relative), and every file it holds is announced."""
    from pathlib import Path

    from vision_cal.actions.verify import VerifyOutcome, default_out

    r = check(moved(CAL, z2=0.04, z1=-0.5, base=(5.0, 3.0)), 21)
    add = r.rezero["add_to_offset_deg"]
    assert add == -r.rezero["zero_moved_deg"] and add < 0
    assert r.verdict == f"re-zero joint 2: add {add:+.3f} deg to its controller offset"
    doc = r.to_json()
    assert doc["rezero"]["add_to_offset_deg"] == add and "sign_convention" in doc
    lines = VerifyOutcome(r, Path("check_verify/verify.json"), (),
                          (Path("check_verify/measurement.json"),
                           Path("check_verify/verify.json"))).lines()
    actions = [ln for ln in lines if ln.startswith("  - ")]
    assert any(ln.startswith(f"  - on the controller: add {add:+.4f} deg") for ln in actions)
    assert any(ln.startswith("  - or in the OLP: enter z2 =") for ln in actions)
    assert all(ln.count("add ") <= 1 for ln in lines), lines   # one action a line
    assert lines[-1] == ("wrote check_verify/verify.json (and measurement.json beside it: "
                         "the photos as measured)")
    assert default_out("check/") == Path("check_verify")
    assert default_out("runs/check") == Path("runs/check_verify")


def test_still_good_names_what_its_bound_is_a_multiple_of():
    """The bound is the tolerance factor times the larger of the promised error and the
    check's noise floor: "still good" names that one with its value (it always said "the
    promised", also when the floor set the bound)."""
    rng = np.random.default_rng(11)
    q, s = random_plan(10, rng)
    xy = CAL.predict(q, s) + rng.normal(0, NOISE_MM, (10, 2))
    ids = [f"c{i:02d}" for i in range(10)]
    promised = CAL_DOC["validation_rms_mm"]["final_model"]
    r = compare(CAL, CAL_DOC, ids, q, s, xy)
    assert r.verdict == "still good" and f"the promised {promised:.4f} mm" in r.reasons[0]
    r = compare(CAL, CAL_DOC, ids, q, s, xy, noise_floor_mm=2 * promised)
    assert r.verdict == "still good" and "promised" not in r.reasons[0]
    assert f"2 x the check's noise floor {2 * promised:.4f} mm" in r.reasons[0]
    assert abs(r.bound_mm - 4 * promised) < 1e-12
