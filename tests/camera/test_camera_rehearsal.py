"""README "Calibrate your camera" through the command line with no robot.

A camera on the arm: the marker field, the designed poses, ``vision-cal simulate`` (the
simulated robot stands at each pose and the world's camera photographs the field),
``vision-cal handeye`` and ``vision-cal locate --joints`` (small photos, 640 x 480, and 10
poses keep it quick). A fixed camera: the pilot photographed from one place
(``camera.fixed`` of the simulated robot file), calibrated, then ``locate`` and ``export``
as typed."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from vision_cal.camera.fixed import camera_of, locate
from vision_cal.commands.main import main
from vision_cal.dataset.io import read_json

pytestmark = pytest.mark.render
N_STD = 4.0


def _rehearse(tmp, effects):
    def cli(*a):
        assert main([str(v) for v in a]) == 0, a

    cli("robot-template", "-o", tmp / "robot.yaml", "-q")
    cli("robot-template", "--simulated", "-o", tmp / "true_robot.yaml", "-q")
    t = yaml.safe_load((tmp / "true_robot.yaml").read_text())
    t["hidden"]["effects"] = effects
    t["camera"].update(size_px=[640, 480], f_px=700.0)
    (tmp / "true_robot.yaml").write_text(yaml.safe_dump(t))
    cli("sheet", "--size", "A2", "--field", "--out", tmp / "field", "-q")
    cli("design", tmp / "robot.yaml", "--sheet", tmp / "field" / "sheet.json",
        "--camera-on-arm", "--n-poses", "10", "--repeats", "4", "--out", tmp / "arm", "-q")
    cli("simulate", tmp / "arm", "--truth", tmp / "true_robot.yaml", "--out", tmp / "arm", "-q")
    cli("handeye", tmp / "arm", "--out", tmp / "arm_cal", "-q")
    return read_json(tmp / "arm_cal" / "calibration.json"), read_json(tmp / "arm" / "truth.json")


def test_arm_camera_rehearsal_finds_the_robot_and_the_mount(tmp_path, capsys):
    doc, truth = _rehearse(tmp_path, [])
    p, sd = doc["params"], doc["std"]
    for k in ("L1_mm", "L2_mm", "joint_zero_deg", "base_mm"):
        err = np.subtract(p[k], truth["params"][k])
        assert np.all(np.abs(err) < N_STD * np.asarray(sd[k])), (k, err, sd[k])
    cam = doc["cameras"][0]
    dt = np.array(cam["T_flange_camera"])[:3, 3] - np.array(truth["T_flange_camera"])[:3, 3]
    assert np.all(np.abs(dt) < N_STD * np.asarray(cam["T_flange_camera_std"]["translation_mm"]))
    assert doc["verdict"]["status"] in ("ready", "check"), doc["verdict"]["reasons"]
    # four poses photographed twice: the robot's repeatability measured from them
    assert doc["verdict"]["repeatability_source"] == "4 pairs of photos taken at the same command"
    capsys.readouterr()
    assert main(["locate", str(tmp_path / "arm_cal" / "calibration.json"), "--pixel", "320",
                 "240", "--joints", "30", "60", "45"]) == 0
    assert "robot frame" in capsys.readouterr().out


def test_a_hidden_backlash_is_found_from_both_approach_directions(tmp_path):
    """The designed poses reach each joint from both sides; the simulated robot hides a
    0.1 deg joint-2 backlash (up to 0.13 mm at the flange): the arm fit finds it within 4
    std, the robot within its std, and the residual sits on the floor again."""
    doc, truth = _rehearse(tmp_path, [{"name": "joint_backlash", "joint": 2, "deg": 0.1}])
    (b2,) = [e for e in doc["effects"] if e["joint"] == 2]
    assert abs(b2["deg"] - 0.1) < N_STD * b2["std"], b2
    p, sd = doc["params"], doc["std"]
    for k in ("L1_mm", "L2_mm", "joint_zero_deg", "base_mm"):
        err = np.subtract(p[k], truth["params"][k])
        assert np.all(np.abs(err) < N_STD * np.asarray(sd[k])), (k, err, sd[k])
    assert not doc["verdict"]["floor"]["beyond"], doc["verdict"]


def test_fixed_camera_rehearsal_locates_pixels_and_exports(tmp_path, capsys):
    """The fixed camera's steps: the pilot drawn by the simulated robot and photographed
    three times from one place (``camera.fixed: true``), calibrated; the camera's pixels
    of true sheet points come back to their true robot-frame place within 4 std; locate
    and export run as the README types them."""
    def cli(*a):
        assert main([str(v) for v in a]) == 0, a

    cli("robot-template", "-o", tmp_path / "robot.yaml", "-q")
    cli("robot-template", "--simulated", "-o", tmp_path / "true_robot.yaml", "-q")
    t = yaml.safe_load((tmp_path / "true_robot.yaml").read_text())
    t["camera"].update(fixed=True, photos=3, size_px=[1000, 750], f_px=1100.0)
    t["hidden"]["controller"] = "kinematic"
    (tmp_path / "true_robot.yaml").write_text(yaml.safe_dump(t))
    cli("sheet", "--size", "A2", "--out", tmp_path / "sheet", "-q")
    cli("design", tmp_path / "robot.yaml", "--sheet", tmp_path / "sheet" / "sheet.json",
        "--out", tmp_path / "pilot", "-q")
    cli("simulate", tmp_path / "pilot", "--truth", tmp_path / "true_robot.yaml", "--out",
        tmp_path / "pilot", "-q")
    cli(tmp_path / "pilot", "--out", tmp_path / "cal", "-q")
    cal = tmp_path / "cal" / "calibration.json"
    doc, truth = read_json(cal), read_json(tmp_path / "pilot" / "truth.json")
    assert len(doc["cameras"]) == 1 and len(doc["cameras"][0]["images"]) == 3
    (T_cs,) = {tuple(np.ravel(v)) for v in truth["camera"]["T_cam_sheet"].values()}
    T_cs, K = np.array(T_cs).reshape(4, 4), np.array(truth["camera"]["K"])
    p_s = np.column_stack([np.random.default_rng(2).uniform([-200, -150], [200, 150], (40, 2)),
                           np.zeros(40)])
    pc = p_s @ T_cs[:3, :3].T + T_cs[:3, 3]
    uv = pc[:, :2] / pc[:, 2:] * K[0, 0] + K[:2, 2]
    got = locate(camera_of(doc, 0), uv, 0.0)
    z1 = np.radians(truth["params"]["joint_zero_deg"][0])
    R = np.array([[np.cos(z1), np.sin(z1)], [-np.sin(z1), np.cos(z1)]])
    err = np.array([g.robot_mm[:2] for g in got]) - (p_s[:, :2] - truth["params"]["base_mm"]) @ R.T
    std = np.array([g.robot_std_mm[:2] for g in got])
    assert np.all(np.abs(err) < N_STD * std), np.abs(err / std).max()
    cli("locate", cal, "--pixel", "812.5", "433", "--z-mm", "50", "--robot", tmp_path / "robot.yaml")
    cli("export", cal, "--opencv", tmp_path / "camera.yaml", "--ros", tmp_path / "camera_info.yaml")
    assert "joint command" in capsys.readouterr().out
