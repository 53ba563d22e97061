import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml

from tests.conftest import ROOT, SM5
from vision_cal.commands.main import main
from vision_cal.model.kinematics import forward


def _rot(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])


def _origin(j):
    o = j.find("origin")
    xyz = [float(v) for v in o.get("xyz").split()]
    yaw = float(o.get("rpy").split()[2])
    t = np.eye(4)
    t[:3, 3] = xyz
    return t @ _rot(yaw)


def test_urdf_chain_reproduces_the_model(tmp_path):
    doc = {"format": "vision-cal/calibration/1", "params": SM5.to_json(),
           "effects": [{"name": "joint_backlash", "joint": 2, "deg": 0.1, "std": 0.004,
                        "evidence": {"F": 3.0}}]}
    import json

    (tmp_path / "c.json").write_text(json.dumps(doc))
    assert main(["export", str(tmp_path / "c.json"), "--urdf", str(tmp_path / "r.urdf"),
                 "--yaml", str(tmp_path / "c.yaml"), "-q"]) == 0
    root = ET.parse(tmp_path / "r.urdf").getroot()
    joints = {j.get("name"): j for j in root.findall("joint")}
    for q in ([0.0, 0.0], [35.0, -80.0], [-120.0, 140.0]):
        T = (_origin(joints["joint1"]) @ _rot(math.radians(q[0])) @ _origin(joints["joint2"])
             @ _rot(math.radians(q[1])) @ _origin(joints["pen_tip"]))
        np.testing.assert_allclose(T[:2, 3] * 1000.0, forward(SM5, [q])[0], atol=1e-5)
    side = yaml.safe_load((tmp_path / "r.effects.yaml").read_text())
    assert side["effects"] == [{"name": "joint_backlash", "joint": 2, "deg": 0.1, "std": 0.004}]
    assert yaml.safe_load((tmp_path / "c.yaml").read_text())["params"]["L1_mm"] == SM5.L1_mm


def test_urdf_with_a_tool_takes_joint_3_and_4_limits_from_the_robot_file(tmp_path):
    """Issue 21: ``export --robot`` gives the URDF the robot file's ``joint4_limits_deg``
    and ``joint3_limits_mm`` (without them, the documented defaults +-360 deg and
    -200..0 mm)."""
    import json

    doc = {"format": "vision-cal/calibration/1",
           "params": dict(SM5.to_json(), tool_mm=[30.0, 5.0]), "effects": []}
    (tmp_path / "c.json").write_text(json.dumps(doc))
    robot = tmp_path / "robot.yaml"
    robot.write_text((ROOT / "fixtures" / "robot_sm5.yaml").read_text()
                     + "joint4_limits_deg: [-200, 120]\njoint3_limits_mm: [-150, 5]\n")

    def limits(urdf, name):
        j = {j.get("name"): j for j in ET.parse(urdf).getroot().findall("joint")}[name]
        lim = j.find("limit")
        return float(lim.get("lower")), float(lim.get("upper"))

    def joint4_limits(urdf):
        return tuple(math.degrees(v) for v in limits(urdf, "joint4"))

    assert main(["export", str(tmp_path / "c.json"), "--urdf", str(tmp_path / "d.urdf"),
                 "-q"]) == 0
    assert joint4_limits(tmp_path / "d.urdf") == pytest.approx((-360.0, 360.0), abs=1e-6)
    assert limits(tmp_path / "d.urdf", "joint3") == pytest.approx((-0.2, 0.0), abs=1e-9)
    assert main(["export", str(tmp_path / "c.json"), "--urdf", str(tmp_path / "r.urdf"),
                 "--robot", str(robot), "-q"]) == 0
    assert joint4_limits(tmp_path / "r.urdf") == pytest.approx((-200.0, 120.0), abs=1e-6)
    assert limits(tmp_path / "r.urdf", "joint3") == pytest.approx((-0.15, 0.005), abs=1e-9)
