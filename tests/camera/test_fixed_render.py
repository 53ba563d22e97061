"""A still camera on rendered photos: its pose in the robot frame and pixel -> robot.

One small series (800 x 600 px, 10 photos from one place, about 0.6 mm per pixel) is
rendered and calibrated once for the module. Truth: the world's true robot (z1, base) and
the camera's true ``T_cam_sheet`` in truth.json. Bounds: 4 reported std; the issue's
0.05 mm at the sheet's plane is for this camera as well (its std is ~0.015 mm).
"""

from __future__ import annotations

import copy
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from vision_cal.estimate.paper import pilot_params
from vision_cal.camera.export import quaternion_xyzw, transform_path
from vision_cal.camera.fixed import camera_of, locate
from vision_cal.commands.main import main
from vision_cal.dataset.io import read_json
from vision_cal.actions.pipeline import calibrate_dataset
from vision_cal.world import dataset as ds
from vision_cal.world.scene import scene_from_dict

ROOT = Path(__file__).resolve().parents[2]
N_STD = 4.0


@pytest.fixture(scope="module")
def still(tmp_path_factory):
    d = yaml.safe_load((ROOT / "renders" / "small.yaml").read_text())
    d["seed"] = 41
    d["camera"].update(n_views=1, moving=False, tilt_deg=[5.0, 12.0])
    sc = scene_from_dict(copy.deepcopy(d), file="still-scene")
    tmp = tmp_path_factory.mktemp("still")
    folder = ds.render_dataset(sc, tmp / "data", pilot=pilot_params)
    run = calibrate_dataset(folder, out_dir=tmp / "out", truth=True)
    return tmp, run.out_path, run.document, read_json(folder / "truth.json")


def _truth(truth):
    """True T_sheet_robot written from the contract (p_S = base + Rot(z1) p_R, z kept), the
    true T_cam_sheet and K."""
    tp = truth["params"]
    z1 = np.radians(tp["joint_zero_deg"][0])
    T_sr = np.array([[np.cos(z1), -np.sin(z1), 0, tp["base_mm"][0]],
                     [np.sin(z1), np.cos(z1), 0, tp["base_mm"][1]], [0, 0, 1, 0], [0, 0, 0, 1]])
    (T_cs,) = {tuple(np.ravel(v)) for v in truth["camera"]["T_cam_sheet"].values()}
    T_cs = np.array(T_cs).reshape(4, 4)
    return T_sr, T_cs, np.array(truth["camera"]["K"])


def test_still_camera_found_with_every_photo(still):
    _, _, doc, _ = still
    (cam,) = doc["cameras"]
    assert cam["images"] == [im["file"] for im in doc["images"] if im["status"] == "ok"]
    assert cam["intrinsics"] == "declared"


def test_T_robot_camera_within_its_std(still):
    _, path, doc, truth = still
    cam = camera_of(doc, 0)
    T_sr, T_cs, _ = _truth(truth)
    T_true = np.linalg.inv(T_sr) @ np.linalg.inv(T_cs)
    err_t = cam.T_robot_camera[:3, 3] - T_true[:3, 3]
    R = cam.T_robot_camera[:3, :3] @ T_true[:3, :3].T
    err_r = np.degrees(0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]))
    sd = cam.std
    assert np.all(np.abs(err_t) < N_STD * sd[3:6]), (err_t, sd[3:6])
    assert np.all(np.abs(err_r) < N_STD * sd[:3]), (err_r, sd[:3])


@pytest.mark.parametrize("z_mm", [0.0, 30.0])
def test_pixel_to_robot_within_std(still, z_mm):
    """True sheet points (at the plane and raised) projected by the true camera come back
    to their true robot-frame place within 4 std, and within 0.05 mm at the plane."""
    _, _, doc, truth = still
    cam = camera_of(doc, 0)
    T_sr, T_cs, K = _truth(truth)
    rng = np.random.default_rng(7)
    p_s = np.column_stack([rng.uniform(-200, 200, 25), rng.uniform(-120, 120, 25),
                           np.full(25, z_mm)])
    p_c = p_s @ T_cs[:3, :3].T + T_cs[:3, 3]
    uv, _ = cv2.projectPoints(p_c.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, None)
    got = locate(cam, uv.reshape(-1, 2), z_mm)
    p_r = p_s @ np.linalg.inv(T_sr)[:3, :3].T + np.linalg.inv(T_sr)[:3, 3]
    err = np.array([g.robot_mm for g in got]) - p_r
    std = np.array([g.robot_std_mm for g in got])
    assert np.allclose(err[:, 2], 0.0, atol=1e-9)
    assert np.all(np.abs(err[:, :2]) < N_STD * std[:, :2]), np.abs(err[:, :2] / std[:, :2]).max()
    if z_mm == 0.0:
        assert np.hypot(*err[:, :2].T).max() < 0.05
    # the sheet point printed beside it is the same point
    assert np.allclose([g.sheet_mm for g in got], p_s, atol=1e-6 + 4 * std.max())


def test_locate_cli_and_csv(still, capsys):
    tmp, path, doc, _ = still
    assert main(["locate", str(path), "--pixel", "400", "300", "--z-mm", "20"]) == 0
    out = capsys.readouterr().out
    assert "robot frame" in out and "z 20.0000" in out
    cam = camera_of(doc, 0)
    (p,) = locate(cam, [[400.0, 300.0]], 20.0)
    assert f"x {p.robot_mm[0]:.4f} y {p.robot_mm[1]:.4f}" in out
    src = tmp / "pixels.csv"
    src.write_text("id,u_px,v_px,z_mm\na,400,300,20\nb,10.5,20,\n")
    out_csv = tmp / "points.csv"
    robot = ROOT / "fixtures" / "robot_sm5.yaml"
    assert main(["locate", str(path), "--csv", str(src), "-o", str(out_csv),
                 "--robot", str(robot), "-q"]) == 0
    rows = out_csv.read_text().splitlines()
    assert rows[0].startswith("id,u_px,v_px,z_mm,x_mm,y_mm") and len(rows) == 3
    assert rows[1].split(",")[4] == f"{p.robot_mm[0]:.5f}"
    assert rows[2].split(",")[3] == "0"          # empty z_mm: the --z-mm default


@pytest.mark.parametrize("argv,field", [
    (["--pixel", "5000", "10"], "--pixel"),
    (["--pixel", "1", "1", "--camera", "3"], "--camera"),
    ([], "--pixel"),
])
def test_locate_bad_input_one_line_exit_2(still, capsys, argv, field):
    _, path, _, _ = still
    assert main(["locate", str(path), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and field in err[0]


def test_export_read_back_by_opencv_and_ros(still):
    tmp, path, doc, _ = still
    cam = camera_of(doc, 0)
    cv_path, ros_path = tmp / "camera.yaml", tmp / "camera_info.yaml"
    assert main(["export", str(path), "--opencv", str(cv_path), "--ros", str(ros_path),
                 "-q"]) == 0
    fs = cv2.FileStorage(str(cv_path), cv2.FILE_STORAGE_READ)
    try:
        assert np.allclose(fs.getNode("camera_matrix").mat(), cam.K)
        assert np.allclose(fs.getNode("distortion_coefficients").mat().ravel(), cam.dist)
        assert np.allclose(fs.getNode("T_robot_camera").mat(), cam.T_robot_camera)
        assert int(fs.getNode("image_width").real()) == cam.size_px[0]
    finally:
        fs.release()
    info = yaml.safe_load(ros_path.read_text())
    assert np.allclose(np.reshape(info["camera_matrix"]["data"], (3, 3)), cam.K)
    assert info["distortion_model"] == "plumb_bob"
    tf = yaml.safe_load(transform_path(ros_path).read_text())
    x, y, z, w = tf["rotation_xyzw"]
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    assert np.allclose(R, cam.T_robot_camera[:3, :3], atol=1e-9)
    assert np.allclose(np.array(tf["translation_m"]) * 1000, cam.T_robot_camera[:3, 3])
    assert np.allclose(quaternion_xyzw(R), [x, y, z, w])
