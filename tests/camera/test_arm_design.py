"""``vision-cal design --camera-on-arm``: poses over the marker field and their program."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from vision_cal.commands.main import main
from vision_cal.dataset.robot import load_robot_file
from vision_cal.kinematics import forward

ROOT = Path(__file__).resolve().parents[2]


def test_camera_poses_cover_the_field_both_elbows_and_joint_4(tmp_path):
    robot_path = ROOT / "fixtures" / "robot_sm5.yaml"
    assert main(["sheet", "--size", "A2", "--field", "--out", str(tmp_path / "field"), "-q"]) == 0
    assert main(["design", str(robot_path), "--sheet", str(tmp_path / "field" / "sheet.json"),
                 "--camera-on-arm", "--n-poses", "16", "--out", str(tmp_path / "arm"),
                 "-q"]) == 0
    s = json.loads((tmp_path / "arm" / "session.json").read_text())
    robot = load_robot_file(robot_path)
    q = np.array([p["joints_deg"] for p in s["poses"]])
    j4 = np.array([p["j4_deg"] for p in s["poses"]])
    xy = forward(robot.nominal.params, q)
    c = np.concatenate([m["corners_mm"] for m in s["sheet"]["markers"]])
    assert np.all((xy > c.min(axis=0) + 59) & (xy < c.max(axis=0) - 59))
    elbow = np.sign(np.sin(np.radians(q[:, 1] + robot.nominal.params.z2_deg)))
    assert (elbow > 0).sum() == (elbow < 0).sum() == 8
    assert j4.max() - j4.min() > 300             # joint 4 turned: L2 and the camera split
    lim = np.array(robot.joint_limits_deg)
    assert np.all((q >= lim[:, 0]) & (q <= lim[:, 1]))
    prg = (tmp_path / "arm" / "program.prg").read_text()
    assert prg.count("On 8") == 16 and prg.count("Off 8") == 16
    assert f"{q[0, 0]:.4f}, {q[0, 1]:.4f}" in prg
