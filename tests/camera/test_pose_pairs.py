"""Hand-eye from pose pairs (issue 32): the world's pairs (worlds/pose_pairs.py, its own
robot and camera code) fed to the estimator (camera/pose_pairs.py).

Bounds: "within 2 std" (the issue's done-when) read jointly: the error of X's six
identifiable parameters inside the 95 % region of their reported covariance (the
chi-square's 95 % point on 6 dof; each parameter alone within 2 std fails one seed in four
with a right std). The std's calibration over many seeds, parameter by parameter, is
bench/handeye_pairs.py's (RMS of error/std near 1, 2 std holding ~95 %)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy import stats
from scipy.spatial.transform import Rotation

from vision_cal.camera.pose_pairs import (LABELS, PairsFailed, PosePair, closed_form,
                                          fit_pose_pairs)
from vision_cal.dataset.calibration_result import METHODS_EXTRA, CalibrationResult
from vision_cal.camera.poses_file import read_poses
from vision_cal.errors import VisionCalError
from worlds.pose_pairs import simulate_pairs
from vision_cal.world.truth_model import TrueRobot
from vision_cal.schema import validate

TRUTH = TrueRobot(344.05, 259.87, (-2.57, -8.13), (-424.26, -230.35))
N_STD = 2.0
#: the 95 % region of a 6-D normal error (the joint "2 std")
REGION_6 = float(stats.chi2.ppf(0.95, 6))
PX = {"noise_px": 0.1}
POSE = {"noise_px": None, "noise_mm": 1.0, "noise_deg": 0.5}


def _pairs(w, ids=None) -> list[PosePair]:
    return [PosePair(f"p{i:02d}" if ids is None else ids[i], a, b)
            for i, (a, b) in enumerate(zip(w["A"], w["B"]))]


def _within(fit, X_true) -> float:
    """The error's squared Mahalanobis distance under the reported covariance of X."""
    e = _errors(fit, X_true)
    return float(e @ np.linalg.solve(fit.cov[:6, :6], e))


def _errors(fit, X_true) -> np.ndarray:
    """(rotation about the parent axes (3) deg, translation (3) mm) of the fit's X."""
    dr = np.degrees(Rotation.from_matrix(fit.X[:3, :3] @ X_true[:3, :3].T).as_rotvec())
    return np.concatenate([dr, fit.X[:3, 3] - X_true[:3, 3]])


@pytest.mark.parametrize("mount,noise,seed", [("arm", PX, 3201), ("arm", POSE, 3202),
                                              ("fixed", PX, 3203), ("fixed", POSE, 3204)])
def test_the_camera_is_within_two_std_of_the_truth(mount, noise, seed):
    """New seeds, 0.1 px of corner noise (solved by PnP) or 1 mm / 0.5 deg on the board's
    pose: every identifiable direction of X within 2 reported std; no pair left out."""
    w = simulate_pairs(TRUTH, 20, seed=seed, mount=mount, **noise)
    fit = fit_pose_pairs(_pairs(w), mount, z_mm=float(w["Y"][2, 3]))
    assert fit and not fit.outliers and not fit.not_identifiable
    assert _within(fit, w["X"]) < REGION_6, (_errors(fit, w["X"]), np.sqrt(np.diag(fit.cov)))
    # the std is not so loose that anything passes: the scatter the pairs were given
    assert 0.5 < fit.sigma_mm / (noise.get("noise_mm") or fit.sigma_mm) < 1.5


def test_the_height_a_scara_cannot_see_is_flagged_and_fixed_by_the_target_plane():
    """Without the target's height the camera's z is reported not identifiable (std None);
    the other directions are the same fit. Given the height, z is within 2 std."""
    w = simulate_pairs(TRUTH, 16, seed=3210, mount="arm", **POSE)
    free = fit_pose_pairs(_pairs(w), "arm")
    assert [d["label"] for d in free.not_identifiable] == ["X_z_mm"]
    assert "vertical axis" in free.not_identifiable[0]["reason"]
    assert free.std()["X"]["translation_mm"][2] is None
    # a target 25 mm above the robot frame's z = 0: the camera found 25 mm higher
    lifted = simulate_pairs(TRUTH, 16, seed=3210, mount="arm", **POSE)
    lifted["A"][:, 2, 3] -= 25.0                # the robot frame's origin 25 mm higher
    a = fit_pose_pairs(_pairs(lifted), "arm", z_mm=-25.0)
    b = fit_pose_pairs(_pairs(w), "arm", z_mm=0.0)
    assert abs(a.X[2, 3] - b.X[2, 3]) < 1e-6
    assert not b.not_identifiable
    sd = np.sqrt(np.diag(b.cov))
    assert abs(b.X[2, 3] - w["X"][2, 3]) < N_STD * sd[5]


def test_outlier_pairs_are_named_and_left_out():
    """Two pairs whose board pose is off by 12 mm / 5 deg (a misdetection): named, left out,
    the camera still within 2 std; without the rule the fit would move by several std."""
    w = simulate_pairs(TRUTH, 20, seed=3220, mount="arm", **POSE)
    w["B"][4, :3, 3] += [12.0, 0.0, 0.0]
    w["B"][11, :3, :3] = w["B"][11, :3, :3] @ Rotation.from_rotvec([0, np.radians(5.0), 0]).as_matrix()
    fit = fit_pose_pairs(_pairs(w), "arm", z_mm=0.0)
    assert set(fit.outliers) == {"p04", "p11"}
    assert all(("p04" in r or "p11" in r) for r in fit.outlier_reasons)
    assert _within(fit, w["X"]) < REGION_6
    # every pair keeps a residual row, the outliers against the fit without them
    assert np.linalg.norm(fit.residual_mm[4]) > 8.0
    assert fit.inlier.sum() == 18


def test_the_closed_form_is_exact_on_exact_pairs():
    """Noise-free pairs: the 4-DOF closed form alone gives X and Y (1e-9)."""
    for mount in ("arm", "fixed"):
        w = simulate_pairs(TRUTH, 8, seed=3230, mount=mount, noise_px=None)
        A = w["A"] if mount == "arm" else np.linalg.inv(w["A"])
        X, Y = closed_form(A, w["B"], float(w["Y"][2, 3]))
        assert np.allclose(X, w["X"], atol=1e-9) and np.allclose(Y, w["Y"], atol=1e-9)


def test_pairs_that_do_not_turn_cannot_place_the_camera():
    w = simulate_pairs(TRUTH, 8, seed=3240, mount="arm", **POSE)
    A = w["A"].copy()
    A[:, :3, :3] = np.eye(3)                     # the flange never turns
    fit = fit_pose_pairs([PosePair(str(i), a, b) for i, (a, b) in enumerate(zip(A, w["B"]))])
    assert isinstance(fit, PairsFailed) and not fit and "turns" in fit.reason
    assert isinstance(fit_pose_pairs(_pairs(w)[:3]), PairsFailed)


def test_labels_cover_x_then_y():
    assert LABELS[:6] == ("X_rot_x_deg", "X_rot_y_deg", "X_rot_z_deg", "X_x_mm", "X_y_mm",
                          "X_z_mm")


# ---- the file: JSON (4x4 or x,y,z,yaw + rvec/tvec), CSV, units --------------------------

def _xyzyaw(A) -> list[float]:
    return [A[0, 3], A[1, 3], A[2, 3], float(np.degrees(np.arctan2(A[1, 0], A[0, 0])))]


def _write_forms(tmp_path, w, scale=1.0):
    """The same pairs as 4x4 JSON, as x,y,z,yaw + rvec/tvec JSON and as CSV (lengths / scale)."""
    pairs4, pairsv, rows = [], [], ["id,x,y,z,yaw_deg,rvec_x,rvec_y,rvec_z,tvec_x,tvec_y,tvec_z"]
    for i, (A, B) in enumerate(zip(w["A"], w["B"])):
        A, B = A.copy(), B.copy()
        A[:3, 3] /= scale
        B[:3, 3] /= scale
        pairs4.append({"id": f"p{i}", "T_robot_flange": A.tolist(), "T_camera_target": B.tolist()})
        rv = Rotation.from_matrix(B[:3, :3]).as_rotvec().tolist()
        pairsv.append({"id": f"p{i}", "flange_pose": _xyzyaw(A), "target_rvec": rv,
                       "target_tvec": B[:3, 3].tolist()})
        rows.append(",".join([f"p{i}"] + [repr(float(v)) for v in _xyzyaw(A) + rv
                                           + B[:3, 3].tolist()]))
    doc4 = {"format": "vision-cal/poses/1", "mount": "arm", "pairs": pairs4}
    docv = {"format": "vision-cal/poses/1", "mount": "arm", "pairs": pairsv}
    (tmp_path / "p4.json").write_text(json.dumps(doc4))
    (tmp_path / "pv.json").write_text(json.dumps(docv))
    (tmp_path / "p.csv").write_text("\n".join(rows) + "\n")
    return doc4, docv


def test_the_three_forms_read_the_same_pairs_and_units_m_scales(tmp_path):
    w = simulate_pairs(TRUTH, 6, seed=3250, mount="arm", **POSE)
    doc4, docv = _write_forms(tmp_path, w)
    validate(doc4, "poses")
    validate(docv, "poses")
    a = read_poses(tmp_path / "p4.json")
    for other in (read_poses(tmp_path / "pv.json"), read_poses(tmp_path / "p.csv")):
        for p, q in zip(a.pairs, other.pairs):
            assert p.id == q.id
            assert np.allclose(p.T_robot_flange, q.T_robot_flange, atol=1e-9)
            assert np.allclose(p.T_camera_target, q.T_camera_target, atol=1e-9)
    (tmp_path / "m").mkdir()
    _write_forms(tmp_path / "m", w, scale=1000.0)
    m = read_poses(tmp_path / "m" / "p.csv", units="m")
    assert np.allclose(m.pairs[2].T_camera_target, a.pairs[2].T_camera_target, atol=1e-9)
    # metres read as millimetres: refused, naming the field
    with pytest.raises(VisionCalError, match="metres"):
        read_poses(tmp_path / "m" / "p.csv")


@pytest.mark.parametrize("brk,field", [
    (lambda d: d["pairs"][1]["T_robot_flange"].__setitem__(3, [0, 0, 1, 1]),
     "pairs[1].T_robot_flange[3]"),
    (lambda d: d["pairs"][2].__setitem__("T_robot_flange",
                                         _tilted(d["pairs"][2]["T_robot_flange"])),
     "pairs[2].T_robot_flange"),
    (lambda d: d["pairs"][0].pop("T_camera_target"), "pairs[0]"),
    (lambda d: d.__setitem__("mount", "wrist"), "mount"),
])
def test_a_bad_pairs_file_is_one_line_naming_the_field(tmp_path, brk, field):
    w = simulate_pairs(TRUTH, 6, seed=3260, mount="arm", **POSE)
    doc4, _ = _write_forms(tmp_path, w)
    brk(doc4)
    (tmp_path / "bad.json").write_text(json.dumps(doc4))
    with pytest.raises(VisionCalError) as e:
        read_poses(tmp_path / "bad.json")
    assert e.value.field == field and "\n" not in str(e.value)


def _tilted(T):
    T = np.array(T)
    T[:3, :3] = Rotation.from_euler("x", 20, degrees=True).as_matrix() @ T[:3, :3]
    return T.tolist()


# ---- the command ------------------------------------------------------------------------

def test_handeye_poses_writes_the_calibration_with_its_verdict(tmp_path, capsys):
    """``vision-cal handeye --poses``: calibration.json with cameras[0].T_flange_camera and
    its std, the target's pose, per-pair residuals, the outlier named, the verdict; the
    height flagged without --z-mm and `check`; FOLDER and --poses together refused."""
    from vision_cal.commands.main import main

    w = simulate_pairs(TRUTH, 16, seed=3270, mount="arm", **POSE)
    w["B"][3, :3, 3] += [0.0, 15.0, 0.0]
    _write_forms(tmp_path, w)
    assert main(["handeye", "--poses", str(tmp_path / "p4.json"), "--out",
                 str(tmp_path / "o"), "--z-mm", "0"]) == 0
    doc = json.loads((tmp_path / "o" / "calibration.json").read_text())
    r = CalibrationResult.from_json(doc)   # written through it: the method's blocks in extra
    assert r.to_json() == doc and set(r.extra) <= set(METHODS_EXTRA["pose_pairs"])
    cam = doc["cameras"][0]
    assert cam["mount"] == "arm" and len(cam["T_flange_camera"]) == 4
    assert doc["outliers"] == ["p3"] and doc["pairs"][3]["status"] == "outlier"
    assert "p3" in doc["pairs"][3]["reason"]
    assert all(p["residual_mm"] >= 0 and p["residual_deg"] >= 0 for p in doc["pairs"])
    assert doc["verdict"]["status"] == "check" and "p3" in " ".join(doc["verdict"]["reasons"])
    sd = cam["T_flange_camera_std"]["translation_mm"]
    assert all(v is not None and v > 0 for v in sd)
    assert "T_robot_target" in cam and cam["target_z_from"] == "given"
    # no height given: the camera's z not identifiable (null std) and said so
    assert main(["handeye", "--poses", str(tmp_path / "p.csv"), "--out", str(tmp_path / "c"),
                 "-q"]) == 0
    doc = json.loads((tmp_path / "c" / "calibration.json").read_text())
    assert doc["cameras"][0]["T_flange_camera_std"]["translation_mm"][2] is None
    assert doc["not_identifiable"][0]["label"] == "X_z_mm"
    assert any("not identifiable" in r for r in doc["verdict"]["reasons"])
    capsys.readouterr()
    assert main(["handeye", str(tmp_path), "--poses", str(tmp_path / "p.csv"), "--out",
                 str(tmp_path / "d")]) == 2
    assert "--poses" in capsys.readouterr().err


def test_the_fixture_finds_its_camera_and_names_its_misdetected_pair():
    """fixtures/handeye_pairs/: X within the 95 % region of its covariance around the
    truth it ships, p09 (moved 8 mm) named and left out."""
    root = Path(__file__).resolve().parents[2] / "fixtures" / "handeye_pairs"
    pf = read_poses(root / "pairs.json")
    fit = fit_pose_pairs(list(pf.pairs), pf.mount, z_mm=0.0)
    truth = json.loads((root / "truth.json").read_text())
    assert fit.outliers == ("p09",)
    assert _within(fit, np.array(truth["T_flange_camera"])) < REGION_6


def test_handeye_poses_keeps_the_pairs_folder_and_an_earlier_run(tmp_path, capsys):
    """``--out`` the folder holding the pairs file is refused (exit 2, the input's folder
    unchanged); a second run into the same folder moves the first one's result to
    previous/ (the output owner, issue 30)."""
    from vision_cal.commands.main import main

    w = simulate_pairs(TRUTH, 12, seed=3275, mount="arm", **POSE)
    _write_forms(tmp_path, w)
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(["handeye", "--poses", str(tmp_path / "p4.json"), "--out", str(tmp_path),
                 "-q"]) == 2
    assert "holds the input --poses" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    out = tmp_path / "o"
    for _ in range(2):
        assert main(["handeye", "--poses", str(tmp_path / "p4.json"), "--out", str(out),
                     "-q"]) == 0
    assert (out / "calibration.json").is_file()
    assert (out / "previous" / "handeye" / "calibration.json").is_file()
