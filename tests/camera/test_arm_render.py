"""The arm's camera on rendered photos: ``vision-cal handeye`` end to end.

The world (render/arm_camera.py) photographs a dense marker field from a camera on the true
robot (0.01 mm repeatability per photo); the estimator reads session.json ``poses`` and the
photos. Bounds: 4 reported std."""

from __future__ import annotations

import json

import numpy as np
import pytest

from vision_cal.commands.main import main
from vision_cal.dataset.io import read_json
from vision_cal.render.arm_camera import render_arm_dataset

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


def test_rendered_clean_poses_are_judged_on_the_noise_floor(arm):
    """Photos of a robot with no hidden effect: the residual sits on the floor the corner
    noise and the repeatability make (1 within its spread on ~16 dof: 4 std ~ 0.7)."""
    _, doc, _ = arm
    v = doc["verdict"]
    assert v["status"] in ("ready", "check"), v["reasons"]
    assert 0.3 < v["residual_over_floor"] < 1.7, v["floor"]
    assert len(doc["poses"]) == 12 and doc["identifiability"]["n_params"] == 12


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


def test_bad_pose_field_one_line_exit_2(arm, tmp_path, capsys):
    folder, _, _ = arm
    s = read_json(folder / "session.json")
    s["poses"][1]["joints_deg"] = [0.0, "x"]
    (tmp_path / "session.json").write_text(json.dumps(s))
    assert main(["handeye", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "poses[1].joints_deg" in err[0]
