"""`vision-cal calibrate` on marks drawn at several j4_deg (measured_mm from the world's own
truth model): tool_mm in calibration.json within 4 reported std, read back for planning;
one j4_deg says the tool is folded into L2 and z2."""

import json
from pathlib import Path

import numpy as np

from tests.tool.oracle import tool_angle_deg
from vision_cal.dataset.calibration import load_calibration
from vision_cal.actions.pipeline import calibrate_dataset
from vision_cal.world.truth_model import TrueRobot

PARAMS = {"L1_mm": 344.05, "L2_mm": 259.87, "joint_zero_deg": [-2.57, -8.13],
          "base_mm": [-424.26, -230.35]}
TOOL = [-18.7, 22.4]


def _session(tmp_path, j4, q, effects=(), seed=7, name="ds", approach=None):
    rng = np.random.default_rng(seed)
    truth = TrueRobot.from_json({**PARAMS, "tool_mm": TOOL}, list(effects))
    # the world's own approach side for joint 4: the sign of its last motion (start 0, +1)
    prev, side, s4 = 0.0, 1.0, []
    for v in j4:
        side = np.sign(v - prev) or side
        s4.append(side)
        prev = v
    a12 = np.ones((len(q), 2)) if approach is None else np.asarray(approach, float)
    s = np.column_stack([a12, s4])
    xy = truth.pen_mm(np.column_stack([q, j4]), s) + rng.normal(0, 0.01, (len(q), 2))
    marks = [{"id": f"c{i:02d}", "joints_deg": list(map(float, qi)), "j4_deg": float(a),
              "approach": [int(v) for v in ai], "measured_mm": list(map(float, p))}
             for i, (qi, a, ai, p) in enumerate(zip(q, j4, a12, xy))]
    d = tmp_path / name
    d.mkdir()
    (d / "session.json").write_text(json.dumps({
        "format": "vision-cal/1",
        "robot": {**PARAMS, "home_deg": [0, 0], "tool_mm": [-20.0, 20.0]},
        "marks": marks}))
    return d


def test_lsq_tool_and_joint4_scale_through_the_pipeline(tmp_path):
    rng = np.random.default_rng(11)
    n = 36
    q = np.column_stack([rng.uniform(10, 100, n), rng.uniform(-110, -40, n)])
    j4 = rng.uniform(-160, 160, n)
    d = _session(tmp_path, j4, q, [{"name": "joint_scale", "joint": 4, "scale": 0.004}])
    run = calibrate_dataset(d, out_dir=tmp_path / "out")
    doc = run.document
    tool, std = np.array(doc["params"]["tool_mm"]), np.array(doc["std"]["tool_mm"])
    assert np.all(np.abs(tool - TOOL) < 4 * std), (tool, std)
    (e,) = doc["effects"]
    assert e["name"] == "joint_scale" and e["joint"] == 4
    assert abs(e["scale"] - 0.004) < 4 * e["std"]
    model, _ = load_calibration(run.out_path)
    np.testing.assert_allclose(model.tool.tool_mm, tool)


def test_joint2_backlash_found_while_joint4_turns(tmp_path):
    """The diagnosis runs with the tool: a hidden joint-2 backlash is named (within 4 std)
    beside the tool and joint 4's gear error, and nothing else is claimed."""
    rng = np.random.default_rng(21)
    n = 60
    q = np.column_stack([rng.uniform(0, 110, n), rng.uniform(-120, -30, n)])
    j4 = rng.uniform(-160, 160, n)
    app = np.where(rng.random((n, 2)) < 0.5, -1, 1)
    d = _session(tmp_path, j4, q, [{"name": "joint_backlash", "joint": 2, "deg": 0.05},
                                   {"name": "joint_scale", "joint": 4, "scale": 0.004}],
                 approach=app)
    doc = calibrate_dataset(d, out_dir=tmp_path / "out").document
    tool, std = np.array(doc["params"]["tool_mm"]), np.array(doc["std"]["tool_mm"])
    assert np.all(np.abs(tool - TOOL) < 4 * std), (tool, std)
    named = {(e["name"], e["joint"]): e for e in doc["effects"]}
    assert set(named) == {("joint_backlash", 2), ("joint_scale", 4)}, named
    b = named[("joint_backlash", 2)]
    assert abs(b["deg"] - 0.05) < 4 * b["std"], b
    assert "tool" not in {e["name"] for e in doc["effects"]}


def test_paper_method_on_joint4_through_the_pipeline(tmp_path):
    q = [[0, -60], [30, -60], [60, -60], [30, -90], [30, -30], [30, -60], [30, -60], [30, -60]]
    j4 = [0, 0, 0, 0, 0, -120, 60, 150]
    d = _session(tmp_path, np.array(j4, float), np.array(q, float))
    run = calibrate_dataset(d, out_dir=tmp_path / "out", method="paper")
    doc = run.document
    err = np.subtract(doc["params"]["tool_mm"], TOOL)
    assert np.all(np.abs(err) < 4 * np.array(doc["std"]["tool_mm"])), (err, doc["std"])
    from vision_cal.schema import validate

    validate(json.loads(run.out_path.read_text()), "calibration")
    assert doc["tool"]["identified"] is True


def test_one_j4_is_folded(tmp_path):
    rng = np.random.default_rng(3)
    q = np.column_stack([rng.uniform(10, 100, 12), rng.uniform(-110, -40, 12)])
    d = _session(tmp_path, np.full(12, 30.0), q)
    doc = calibrate_dataset(d, out_dir=tmp_path / "out").document
    assert doc["tool"]["identified"] is False
    assert "folded into L2 and z2" in doc["tool"]["statement"]
    assert "tool_mm" not in doc["params"]


def test_plan_command_with_theta_writes_q4_and_tlset(tmp_path):
    from vision_cal.commands.main import main
    from vision_cal.dataset.csvio import read_plan

    rng = np.random.default_rng(5)
    n = 30
    q = np.column_stack([rng.uniform(10, 100, n), rng.uniform(-110, -40, n)])
    d = _session(tmp_path, rng.uniform(-160, 160, n), q)
    assert main([str(d), "--out", str(tmp_path / "out"), "-q"]) == 0
    targets = tmp_path / "targets.csv"
    targets.write_text("id,x_mm,y_mm,theta_deg\na,-200.0,50.0,30.0\nb,-150.0,0.0,-120.0\n")
    out = tmp_path / "plan.csv"
    robot = tmp_path / "robot.yaml"   # the controller's tool 1 is the program's to set
    robot.write_text(Path("fixtures/robot_sm5.yaml").read_text() + "  tool_number: 1\n")
    assert main(["plan", str(tmp_path / "out" / "calibration.json"), str(targets), "-o",
                 str(out), "--program", "spel", "--robot", str(robot),
                 "--force", "-q"]) == 0   # measured_mm: no noise floor, so never "ready"
    text = out.read_text()
    head = text.splitlines()[0].split(",")
    assert "q4_deg" in head and "approach4" in head
    ids, qp, _ = read_plan(out)
    q4 = [float(r.split(",")[head.index("q4_deg")]) for r in text.splitlines()[1:]]
    truth = TrueRobot.from_json({**PARAMS, "tool_mm": TOOL})
    q3 = np.column_stack([qp, q4])
    np.testing.assert_allclose(truth.pen_mm(q3), [[-200, 50], [-150, 0]], atol=0.03)
    np.testing.assert_allclose((tool_angle_deg(truth, q3) - [30, -120] + 180) % 360 - 180, 0,
                               atol=0.05)
    prg = (tmp_path / "plan.prg").read_text()
    assert "TLSet 1, XY(" in prg
    assert f"{q4[0]:.4f})" in prg   # joint 4 of the first target in its JA point


def test_urdf_with_joints_3_4_and_tool_reproduces_the_model(tmp_path):
    import xml.etree.ElementTree as ET

    from vision_cal.model.kinematics import ScaraParams, forward_tool
    from vision_cal.report.export import urdf_text

    p = ScaraParams(344.0, 260.0, -2.5, -8.0, -424.0, -230.0)
    root = ET.fromstring(urdf_text({"params": {**p.to_json(), "tool_mm": TOOL}}))
    joints = {j.get("name"): j for j in root.findall("joint")}
    assert joints["joint3"].get("type") == "prismatic"
    assert joints["tool"].get("type") == "fixed"

    def T(j, yaw=0.0):
        o = j.find("origin")
        x, y, z = (float(v) for v in o.get("xyz").split())
        a = float(o.get("rpy").split()[2]) + yaw
        m = np.eye(3)
        m[:2, :2] = [[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]
        m[:2, 2] = (x, y)
        return m

    for q1, q2, q4 in ((0, 0, 0), (35, -80, 90), (-120, 140, -45)):
        m = (T(joints["joint1"], np.radians(q1)) @ T(joints["joint2"], np.radians(q2))
             @ T(joints["joint3"]) @ T(joints["joint4"], np.radians(q4)) @ T(joints["tool"]))
        np.testing.assert_allclose(m[:2, 2] * 1000, forward_tool(p, [[q1, q2]], q4, TOOL)[0],
                                   atol=1e-5)


def test_joint4_documents_validate_against_the_schemas(tmp_path):
    from vision_cal.schema import validate

    rng = np.random.default_rng(9)
    q = np.column_stack([rng.uniform(10, 100, 20), rng.uniform(-110, -40, 20)])
    d = _session(tmp_path, rng.uniform(-160, 160, 20), q)
    validate(json.loads((d / "session.json").read_text()), "session")
    run = calibrate_dataset(d, out_dir=tmp_path / "out")
    validate(json.loads(run.out_path.read_text()), "calibration")
