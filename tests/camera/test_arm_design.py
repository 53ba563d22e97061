"""``vision-cal design --camera-on-arm``: poses over the marker field and their program."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from vision_cal.commands.main import main
from vision_cal.dataset.robot import load_robot_file
from vision_cal.model.kinematics import forward

ROOT = Path(__file__).resolve().parents[2]


def test_camera_poses_cover_the_field_both_elbows_and_joint_4(tmp_path):
    robot_path = ROOT / "fixtures" / "robot_sm5.yaml"
    assert main(["sheet", "--size", "A2", "--field", "--out", str(tmp_path / "field"), "-q"]) == 0
    assert main(["design", str(robot_path), "--sheet", str(tmp_path / "field" / "sheet.json"),
                 "--camera-on-arm", "--n-poses", "16", "--out", str(tmp_path / "arm"),
                 "-q"]) == 0
    s = json.loads((tmp_path / "arm" / "session.json").read_text())
    robot = load_robot_file(robot_path)
    first = [p for p in s["poses"] if "repeat_of" not in p]       # the 16 distinct poses
    assert len(first) == 16 and len(s["poses"]) == 16 + 6          # 6 taken twice
    q = np.array([p["joints_deg"] for p in first])
    j4 = np.array([p["j4_deg"] for p in first])
    xy = forward(robot.nominal.params, q)
    c = np.concatenate([m["corners_mm"] for m in s["sheet"]["markers"]])
    assert np.all((xy > c.min(axis=0) + 59) & (xy < c.max(axis=0) - 59))
    elbow = np.sign(np.sin(np.radians(q[:, 1] + robot.nominal.params.z2_deg)))
    assert (elbow > 0).sum() == (elbow < 0).sum() == 8
    assert j4.max() - j4.min() > 300             # joint 4 turned: L2 and the camera split
    lim = np.array(robot.joint_limits_deg)
    assert np.all((q >= lim[:, 0]) & (q <= lim[:, 1]))
    prg = (tmp_path / "arm" / "program.prg").read_text()
    assert prg.count("On 8") == 22 and prg.count("Off 8") == 22
    assert f"{q[0, 0]:.4f}, {q[0, 1]:.4f}" in prg


def test_repeated_poses_come_back_from_the_same_sides(tmp_path):
    """Each repeated pose follows its first photo; the program leaves through a via point
    on each joint's approach side and comes back, so the format's approach rule (the
    session's) and the real motion agree: the same sides both times."""
    from vision_cal.model.motion import approach_signs

    robot_path = ROOT / "fixtures" / "robot_sm5.yaml"
    assert main(["sheet", "--size", "A2", "--field", "--out", str(tmp_path / "field"), "-q"]) == 0
    assert main(["design", str(robot_path), "--sheet", str(tmp_path / "field" / "sheet.json"),
                 "--camera-on-arm", "--n-poses", "12", "--repeats", "4",
                 "--out", str(tmp_path / "arm"), "-q"]) == 0
    s = json.loads((tmp_path / "arm" / "session.json").read_text())
    poses = s["poses"]
    q = np.array([p["joints_deg"] for p in poses])
    signs = approach_signs(q, (0.0, 0.0))
    reps = [k for k, p in enumerate(poses) if "repeat_of" in p]
    assert len(reps) == 4 and [p["image"] for p in poses] == [f"pose_{k:03d}.png"
                                                              for k in range(16)]
    prg = (tmp_path / "arm" / "program.prg").read_text()
    for k in reps:
        a, b = poses[k - 1], poses[k]
        assert b["repeat_of"] == a["image"] and b["joints_deg"] == a["joints_deg"]
        assert np.array_equal(signs[k], signs[k - 1])
        via = np.array(b["via_deg"][:2])
        assert np.allclose(np.sign(np.array(b["joints_deg"]) - via), signs[k])
        assert f"{via[0]:.4f}, {via[1]:.4f}" in prg
    assert main(["design", str(robot_path), "--sheet", str(tmp_path / "field" / "sheet.json"),
                 "--camera-on-arm", "--n-poses", "12", "--repeats", "13",
                 "--out", str(tmp_path / "arm2"), "-q"]) == 2
