"""The arm's camera on rendered photos: ``vision-cal handeye`` end to end.

The world (world/arm_camera.py) photographs a dense marker field from a camera on the true
robot (0.01 mm repeatability per photo); the estimator reads session.json ``poses`` and the
photos. Bounds: 4 reported std."""

from __future__ import annotations

import json

import numpy as np
import pytest

from vision_cal.camera.arm import camera_for
from vision_cal.camera.fixed import UNDETERMINED, locate
from vision_cal.commands.main import main
from vision_cal.dataset.calibration_result import METHODS_EXTRA, CalibrationResult
from vision_cal.dataset.io import read_json
from vision_cal.world.arm_camera import render_arm_dataset

TRUTH = {"L1_mm": 344.05, "L2_mm": 259.87, "joint_zero_deg": [-2.57, -8.13],
         "base_mm": [-424.26, -230.35]}
NOMINAL = {"L1_mm": 350.0, "L2_mm": 260.0, "joint_zero_deg": [0.0, 0.0],
           "base_mm": [-410.0, -240.0]}
N_STD = 4.0


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("arm")
    folder = render_arm_dataset(tmp / "data", truth=TRUTH, nominal=NOMINAL, n_poses=12,
                                size_px=(640, 480), f_px=720.0, seed=23)
    s = read_json(folder / "session.json")
    s["poses"].append({"image": "missing.png", "joints_deg": [0.0, 90.0], "j4_deg": 0.0})
    (folder / "session.json").write_text(json.dumps(s))
    assert main(["handeye", str(folder), "--out", str(tmp / "out"), "-q"]) == 0
    return folder, read_json(tmp / "out" / "calibration.json"), read_json(folder / "truth.json")


def test_robot_found_without_a_pen_within_its_std(arm):
    _, doc, _ = arm
    p, sd = doc["params"], doc["std"]
    for k in ("L1_mm", "L2_mm"):
        assert abs(p[k] - TRUTH[k]) < N_STD * sd[k], (k, p[k] - TRUTH[k], sd[k])
    for k in ("joint_zero_deg", "base_mm"):
        err = np.subtract(p[k], TRUTH[k])
        assert np.all(np.abs(err) < N_STD * np.asarray(sd[k])), (k, err, sd[k])
    assert doc["not_identifiable"] == []
    # the poses reach each joint from both sides, so its backlash is fitted: none in this world
    assert [e["joint"] for e in doc["effects"]] == [1, 2]
    for e in doc["effects"]:
        assert abs(e["deg"]) < N_STD * e["std"], e


def test_rendered_clean_poses_are_judged_on_the_noise_floor(arm):
    """Photos of a robot with no hidden effect: the residual sits on the floor the corner
    noise and the repeatability make (1 within its spread on ~16 dof: 4 std ~ 0.7)."""
    _, doc, _ = arm
    v = doc["verdict"]
    assert v["status"] in ("ready", "check"), v["reasons"]
    assert 0.3 < v["residual_over_floor"] < 1.7, v["floor"]
    assert len(doc["poses"]) == 12
    assert doc["identifiability"]["n_params"] == 12 + len(doc["effects"])


def test_T_flange_camera_found_within_its_std(arm):
    _, doc, truth = arm
    cam = doc["cameras"][0]
    X, Xf = np.array(truth["T_flange_camera"]), np.array(cam["T_flange_camera"])
    sd = cam["T_flange_camera_std"]
    dt = Xf[:3, 3] - X[:3, 3]
    assert np.all(np.abs(dt) < N_STD * np.asarray(sd["translation_mm"])), (dt, sd)
    R = Xf[:3, :3] @ X[:3, :3].T
    dr = np.degrees(0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]))
    assert np.all(np.abs(dr) < N_STD * np.asarray(sd["rotation_deg"])), (dr, sd)


def test_a_missing_photo_is_skipped_and_the_rest_used(arm):
    _, doc, _ = arm
    bad = [im for im in doc["images"] if im["status"] != "ok"]
    assert [im["file"] for im in bad] == ["missing.png"] and bad[0]["reason"]
    assert len(doc["cameras"][0]["images"]) == 12
    # written through CalibrationResult: the arm camera's own blocks in its documented extra
    r = CalibrationResult.from_json(doc)
    assert r.to_json() == doc and set(r.extra) <= set(METHODS_EXTRA["arm_camera"])


def test_bad_pose_field_one_line_exit_2(arm, tmp_path, capsys):
    folder, _, _ = arm
    s = read_json(folder / "session.json")
    s["poses"][1]["joints_deg"] = [0.0, "x"]
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "session.json").write_text(json.dumps(s))
    assert main(["handeye", str(tmp_path / "in"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "poses[1].joints_deg" in err[0]


def _true_robot_frame(p_s):
    """Sheet points (N, 3) in the true robot frame (the contract: p_S = base + Rot(z1) p_R)."""
    z1 = np.radians(TRUTH["joint_zero_deg"][0])
    R = np.array([[np.cos(z1), np.sin(z1)], [-np.sin(z1), np.cos(z1)]])
    return (p_s[:, :2] - TRUTH["base_mm"]) @ R.T


@pytest.mark.parametrize("z_mm", [0.0, 30.0])
def test_locate_a_pixel_of_an_arm_photo_against_the_truth(arm, z_mm):
    """True points (at the sheet's plane and raised) projected by a photo's true camera come
    back to their true robot-frame place through the fitted robot and T_flange_camera at
    the photo's commanded joints: within 4 std (the robot's repeatability in it) and 0.05 mm."""
    _, doc, truth = arm
    photo = doc["poses"][3]["image"]
    T_cs = np.array(truth["camera"]["T_cam_sheet"][photo])
    K = np.array(truth["camera"]["K"])
    rng = np.random.default_rng(4)
    centre = np.linalg.inv(T_cs)[:2, 3]
    p_s = np.column_stack([centre + rng.uniform(-40, 40, (30, 2)), np.full(30, z_mm)])
    pc = p_s @ T_cs[:3, :3].T + T_cs[:3, 3]
    uv = pc[:, :2] / pc[:, 2:] * K[0, 0] + K[:2, 2]
    ok = (uv[:, 0] > 0) & (uv[:, 0] < 639) & (uv[:, 1] > 0) & (uv[:, 1] < 479)
    assert ok.sum() > 10
    got = locate(camera_for(doc, 0, photo=photo), uv[ok], z_mm)
    err = np.array([g.robot_mm[:2] for g in got]) - _true_robot_frame(p_s[ok])
    std = np.array([g.robot_std_mm[:2] for g in got])
    assert np.all(np.abs(err) < N_STD * std), np.abs(err / std).max()
    assert np.hypot(*err.T).max() < 0.05


def test_locate_cli_takes_the_arm_command(arm, tmp_path, capsys):
    folder, doc, _ = arm
    cal = tmp_path / "calibration.json"
    cal.write_text(json.dumps(doc))
    pose = doc["poses"][5]
    (tmp_path / "px.csv").write_text("id,u_px,v_px\na,100,80\nb,500,400\n")
    q = [str(v) for v in pose["joints_deg"] + [pose["j4_deg"]]]
    assert main(["locate", str(cal), "--csv", str(tmp_path / "px.csv"), "--joints", *q]) == 0
    rows = capsys.readouterr().out.strip().splitlines()[1:]
    want = locate(camera_for(doc, 0, photo=pose["image"]), [[100, 80], [500, 400]], 0.0)
    for row, w in zip(rows, want):
        assert np.allclose([float(v) for v in row.split(",")[4:6]], w.robot_mm[:2], atol=1e-4)
    assert main(["locate", str(cal), "--pixel", "100", "80"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--joints" in err[0]


def _params_within_std(doc):
    p, sd = doc["params"], doc["std"]
    for k in ("L1_mm", "L2_mm", "joint_zero_deg", "base_mm"):
        err = np.subtract(p[k], TRUTH[k])
        assert np.all(np.abs(err) < N_STD * np.asarray(sd[k])), (k, err, sd[k])


def test_an_undeclared_lens_seen_square_is_said_undetermined(tmp_path, capsys):
    """A camera looking down within 0.5 deg: every view sees the sheet under that same
    tilt, so the focal length trades with the height. The robot is still found; the
    verdict says what is unknown and locate refuses heights off the plane."""
    data = render_arm_dataset(tmp_path / "data", truth=TRUTH, nominal=NOMINAL, n_poses=8,
                              size_px=(640, 480), f_px=720.0, seed=31, tilt_deg=0.5,
                              declare_lens=False)
    assert main(["handeye", str(data), "--out", str(tmp_path / "out"), "-q"]) == 0
    doc = read_json(tmp_path / "out" / "calibration.json")
    assert doc["cameras"][0]["intrinsics"] == UNDETERMINED
    assert doc["verdict"]["status"] == "check"
    assert any("focal length" in r for r in doc["verdict"]["reasons"])
    # the height the views cannot fix: not identifiable, with the std the focal length's
    # own gives it (issue 29), and the truth within it
    assert "cam_z_mm" in doc["not_identifiable"]
    X = np.array(read_json(data / "truth.json")["T_flange_camera"])
    z_sd = doc["cameras"][0]["T_flange_camera_std"]["translation_mm"][2]
    assert z_sd > 1.0 and abs(doc["cameras"][0]["T_flange_camera"][2][3] - X[2, 3]) < N_STD * z_sd
    _params_within_std(doc)
    cal = str(tmp_path / "out" / "calibration.json")
    assert main(["locate", cal, "--pixel", "100", "80", "--photo", "pose_001.png",
                 "--z-mm", "10"]) == 2
    assert "--z-mm" in capsys.readouterr().err


def test_an_undeclared_lens_seen_tilted_is_estimated(tmp_path):
    """A camera tilted 20-25 deg: one view's perspective fixes the focal length (principal
    point at the image centre, as rendered); found within 4 of its std, and the robot and
    T_flange_camera's height within theirs."""
    folder = render_arm_dataset(tmp_path / "data", truth=TRUTH, nominal=NOMINAL, n_poses=10,
                                size_px=(640, 480), f_px=720.0, seed=29, tilt_deg=(20.0, 25.0),
                                declare_lens=False)
    assert main(["handeye", str(folder), "--out", str(tmp_path / "out"), "-q"]) == 0
    doc = read_json(tmp_path / "out" / "calibration.json")
    cam = doc["cameras"][0]
    assert cam["intrinsics"] == "estimated"
    assert abs(cam["K"][0][0] - 720.0) < N_STD * cam["f_px_std"], (cam["K"][0][0], cam["f_px_std"])
    _params_within_std(doc)
    X = np.array(read_json(folder / "truth.json")["T_flange_camera"])
    dz = cam["T_flange_camera"][2][3] - X[2, 3]
    assert abs(dz) < N_STD * cam["T_flange_camera_std"]["translation_mm"][2], dz


def test_one_job_measures_the_same_as_several(arm, tmp_path, capsys):
    """handeye --jobs: the photos measured in one process give the same calibration as
    the fixture's run in every core's (issue 30); run again into the same folder, the
    detections come from its cache, as a pen calibration's do (issue 39)."""
    folder, doc, _ = arm
    assert main(["handeye", str(folder), "--out", str(tmp_path / "one"), "-q", "-j", "1"]) == 0
    one = read_json(tmp_path / "one" / "calibration.json")
    assert one["params"] == doc["params"] and one["images"] == doc["images"]
    capsys.readouterr()
    assert main(["handeye", str(folder), "--out", str(tmp_path / "one"), "-j", "1"]) == 0
    err = capsys.readouterr().err
    assert "12/12 photos" in err and "all from the cache" in err, err
    assert read_json(tmp_path / "one" / "calibration.json")["params"] == doc["params"]


# ------------------------------------------------ what the poses covered (issue 29, valid_for)

def _err_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_the_calibration_says_what_its_poses_covered(arm):
    """handeye writes calibration.json ``valid_for`` (the one owner's block, built from its
    poses): the joint ranges and sides the photos were taken from, joint 4's angles, the
    camera's height above the sheet (where locate can map a pixel)."""
    from vision_cal.dataset.valid_for import build

    _, doc, _ = arm
    vf = doc["valid_for"]
    assert vf == json.loads(json.dumps(build({k: v for k, v in doc.items()
                                              if k != "valid_for"})))
    q = np.array([p["joints_deg"] for p in doc["poses"]])
    assert vf["joints_deg"] == [[q[:, j].min(), q[:, j].max()] for j in range(2)]
    assert vf["approach_sides"]["1"] == [-1, 1] and vf["approach_sides"]["2"] == [-1, 1]
    assert vf["joint4_deg"] == sorted({round(p["j4_deg"], 6) for p in doc["poses"]})
    z = doc["cameras"][0]["T_flange_camera"][2][3]
    assert vf["cameras"][0]["locate_heights_mm"] == [0.0, z]
    assert vf["not_identified"] == [] and "within_valid_for" not in doc["verdict"]


def test_a_joint_reached_from_one_side_only_is_never_ready(arm, tmp_path):
    """The same photos with joint 2 always reached from below (poses sorted by q2, home
    below them all): its backlash cannot be identified; the verdict, judged against
    valid_for as the pen's is, is "check", names it and what to draw."""
    folder, doc, _ = arm
    s = read_json(folder / "session.json")
    s["poses"] = sorted(s["poses"], key=lambda p: p["joints_deg"][1])
    s["robot"]["home_deg"] = [0.0, -149.0]
    one = tmp_path / "one"
    one.mkdir()
    for p in s["poses"]:
        if (folder / p["image"]).exists():
            (one / p["image"]).write_bytes((folder / p["image"]).read_bytes())
    (one / "session.json").write_text(json.dumps(s))
    assert main(["handeye", str(one), "--out", str(tmp_path / "out"), "-q"]) == 0
    d = read_json(tmp_path / "out" / "calibration.json")
    assert d["valid_for"]["approach_sides"]["2"] == [1]
    v = d["verdict"]
    assert v["status"] == "check", v
    assert any("joint_backlash(joint 2)" in r for r in v["reasons"]), v["reasons"]
    assert v["within_valid_for"] in ("ready", "check")


def test_locate_refuses_heights_the_arm_camera_did_not_see(arm, tmp_path, capsys):
    """--z-mm below the sheet (or above the camera): outside valid_for, one line; with
    --force the extrapolation is said on the console and in the CSV."""
    _, doc, _ = arm
    cal = tmp_path / "calibration.json"
    cal.write_text(json.dumps(doc))
    q = [str(v) for v in doc["poses"][5]["joints_deg"] + [doc["poses"][5]["j4_deg"]]]
    base = ["locate", str(cal), "--pixel", "320", "240", "--joints", *q, "-q"]
    assert main(base + ["--z-mm", "20"]) == 0
    capsys.readouterr()
    assert main(base + ["--z-mm", "-30"]) == 1   # nothing located (a request per pixel)
    line = _err_line(capsys)
    assert "valid_for.heights" in line and "-30" in line, line
    (tmp_path / "px.csv").write_text("id,u_px,v_px,z_mm\na,320,240,-30\n")
    out = tmp_path / "loc.csv"
    assert main(["locate", str(cal), "--csv", str(tmp_path / "px.csv"), "--joints", *q,
                 "-o", str(out), "-q", "--force"]) == 0
    assert "valid_for" in capsys.readouterr().err
    assert "heights" in out.read_text().splitlines()[1].split(",")[-1]


@pytest.mark.parametrize("joints", [["500", "60"], ["30", "-151"], ["30", "60", "400"]])
def test_locate_refuses_joints_the_robot_cannot_reach_even_forced(arm, tmp_path, capsys,
                                                                  joints):
    """--joints beyond the joint limits (the defaults here; the robot file's with --robot):
    no photo was ever taken there, --force or not."""
    _, doc, _ = arm
    cal = tmp_path / "calibration.json"
    cal.write_text(json.dumps(doc))
    assert main(["locate", str(cal), "--pixel", "320", "240", "--joints", *joints,
                 "--force", "-q"]) == 2
    line = _err_line(capsys)
    assert "--joints" in line and "beyond" in line and "limits" in line, line
