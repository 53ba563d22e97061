"""Robot programs: every mark, in order, through its overshoot, joints as planned.

A small SPEL+ parser reads the program back: statements inside Function main ... Fend,
comments after an apostrophe, Go JA(j1, j2, j3, j4) points.
"""

import csv
import io
import json
import re

import numpy as np
import pytest

from tests.design.conftest import ROBOT
from vision_cal.dataset.robot import load_robot_file
from vision_cal.plan.calibration_plan import PlannedMark
from vision_cal.program import program_points, write_program

NUM = r"\s*(-?\d+(?:\.\d+)?)\s*"
GO_JA = re.compile(rf"^Go JA\({NUM},{NUM},{NUM},{NUM}\)$")


def parse_spel(text: str) -> dict:
    """{'header': [...], 'setup': {...}, 'ops': [(op, args)]}; raises on anything else."""
    lines = text.replace("\r\n", "\n").split("\n")
    header, body, inside, ended = [], [], False, False
    for raw in lines:
        code, _, comment = raw.partition("'")
        code = code.strip()
        if not inside:
            if code == "Function main":
                inside = True
            elif code:
                raise AssertionError(f"code outside a function: {raw!r}")
            else:
                header.append(comment.strip())
            continue
        if code == "Fend":
            ended = True
            inside = False
            continue
        if code:
            body.append((code, comment.strip()))
    assert ended, "no Fend"
    setup, ops = {}, []
    for code, comment in body:
        word, _, rest = code.partition(" ")
        if word in ("Motor", "Power"):
            setup[word] = rest
        elif word == "Speed":
            setup[word] = float(rest)
        elif word == "Accel":
            setup[word] = tuple(float(v) for v in rest.split(","))
        elif word == "Go":
            m = GO_JA.match(code)
            assert m, f"not a joint-angle point: {code!r}"
            ops.append(("go", tuple(float(v) for v in m.groups()), comment))
        elif word == "Wait":
            ops.append(("wait", float(rest), comment))
        elif word == "Print":
            ops.append(("print", rest.strip('"'), comment))
        else:
            raise AssertionError(f"unexpected statement {code!r}")
    return {"header": header, "setup": setup, "ops": ops}


def marks_of(session: dict) -> list[PlannedMark]:
    """Planned marks with their overshoot via points as the design wrote them."""
    over = load_robot_file(ROBOT).overshoot_deg
    out = []
    for m in session["marks"]:
        q, s = np.array(m["joints_deg"]), np.array(m["approach"])
        out.append(PlannedMark(m["id"], tuple(q), m["role"], tuple(s), (tuple(q - s * over),)))
    return out


def drawn_marks(ops, up, down):
    """(id order, joints at pen-down, the point driven to just before each mark)."""
    gos = [(a, c) for op, a, c in ops if op == "go"]
    out = []
    for k, (a, c) in enumerate(gos):
        if a[2] == down:
            prev_up = gos[k - 1][0]
            assert prev_up[:2] == a[:2] and prev_up[2] == up, "pen lowered after a move"
            before = gos[k - 2][0]
            after = gos[k + 1][0]
            assert after[:2] == a[:2] and after[2] == up, "pen not raised in place"
            out.append((c.split()[0], a, before))
    return out


@pytest.fixture(scope="module")
def robot():
    return load_robot_file(ROBOT)


@pytest.mark.parametrize("folder", ["pilot_dir", "informative_dir"])
def test_spel_program_draws_every_mark_in_order_through_its_overshoot(request, folder, robot):
    """Catches: a mark missing or out of order, a via point on the wrong side (the joint
    would arrive from the other side of its dead band), joints rounded or swapped."""
    d = request.getfixturevalue(folder)
    s = json.loads((d / "session.json").read_text())
    prog = next(d.glob("*.prg")).read_text()
    p = parse_spel(prog)
    assert p["setup"] == {"Motor": "On", "Power": "Low", "Speed": 20.0, "Accel": (20.0, 20.0)}
    assert any("vision-cal" in h for h in p["header"])
    up, down = robot.require_pen_heights()
    drawn = drawn_marks(p["ops"], up, down)
    assert [i for i, _, _ in drawn] == [m["id"] for m in s["marks"]]
    for (mid, at, before), m in zip(drawn, s["marks"]):
        q = np.array(m["joints_deg"])
        assert np.all(np.abs(np.array(at[:2]) - q) <= 0.5e-4 + 1e-9), mid
        assert at[3] == robot.j4_deg
        # the last motion of each joint onto the mark has the planned sign
        assert np.all(np.sign(np.array(at[:2]) - np.array(before[:2])) == m["approach"]), mid
        assert np.allclose(np.abs(np.array(at[:2]) - np.array(before[:2])),
                           robot.overshoot_deg, atol=1e-4)
    waits = [a for op, a, _ in p["ops"] if op == "wait"]
    assert waits.count(robot.program.pen_dwell_s) >= len(drawn)


def test_csv_point_list_matches_the_plan(pilot_dir, robot, tmp_path):
    s = json.loads((pilot_dir / "session.json").read_text())
    pts = program_points(marks_of(s), home_deg=(0, 0), z2_deg=s["robot"]["joint_zero_deg"][1])
    path = write_program("csv", tmp_path / "p.csv", pts, robot, title="t")
    rows = list(csv.DictReader(io.StringIO(path.read_text())))
    assert rows[0]["kind"] == rows[-1]["kind"] == "home"
    mk = [r for r in rows if r["kind"] == "mark"]
    assert [r["id"] for r in mk] == [m["id"] for m in s["marks"]]
    for i, r in enumerate(rows):
        if r["kind"] != "mark":
            continue
        via = rows[i - 1]
        assert via["kind"] == "via" and via["id"] == r["id"]
        m = s["marks"][[x["id"] for x in s["marks"]].index(r["id"])]
        q = np.array([float(r["j1_deg"]), float(r["j2_deg"])])
        assert np.all(np.abs(q - m["joints_deg"]) <= 0.5e-6 + 1e-12)
        v = np.array([float(via["j1_deg"]), float(via["j2_deg"])])
        assert np.all(np.sign(q - v) == m["approach"])
        assert [int(r["approach1"]), int(r["approach2"])] == m["approach"]
        assert float(r["pen_z_mm"]) == robot.pen_down_mm and float(r["j3_mm"]) == robot.pen_up_mm


def test_no_pen_heights_no_program(tmp_path, pilot_dir):
    from dataclasses import replace

    from vision_cal.errors import VisionCalError

    robot = replace(load_robot_file(ROBOT), pen_up_mm=None, pen_down_mm=None)
    s = json.loads((pilot_dir / "session.json").read_text())
    with pytest.raises(VisionCalError, match="pen_up_mm"):
        write_program("spel", tmp_path / "x.prg", program_points(marks_of(s)), robot, title="t")
    assert not (tmp_path / "x.prg").exists()


def test_plan_command_writes_std_and_the_compensated_program(tmp_path, robot):
    """`vision-cal plan --program spel`: plan.csv gains std_mm, plan.prg draws exactly the
    planned rows. Catches: the program written from other joints than plan.csv's."""
    from tests.conftest import ROOT
    from vision_cal.commands.main import main
    from vision_cal.dataset.csvio import read_plan

    assert main([str(ROOT / "fixtures" / "paper_sm5"), "--out", str(tmp_path / "cal"), "-q"]) == 0
    (tmp_path / "t.csv").write_text("id,x_mm,y_mm\norigin,0,0\na,-60,40\nfar,900,0\n")
    rc = main(["plan", str(tmp_path / "cal" / "calibration.json"), str(tmp_path / "t.csv"),
               "-o", str(tmp_path / "plan.csv"), "--program", "spel", "--robot", str(ROBOT),
               "-q", "--force"])   # the paper's five marks cover little (valid_for)
    assert rc == 3   # far: partial
    rows = {r["id"]: r for r in csv.DictReader(io.StringIO((tmp_path / "plan.csv").read_text()))}
    assert all(0 < float(rows[i]["std_mm"]) < 5 for i in ("origin", "a"))
    assert "far" not in rows or rows["far"]["status"] == "failed"   # out of reach
    ids, q, s = read_plan(tmp_path / "plan.csv")
    up, down = robot.require_pen_heights()
    drawn = drawn_marks(parse_spel((tmp_path / "plan.prg").read_text())["ops"], up, down)
    assert [d[0] for d in drawn] == ids
    for (mid, at, before), qi, si in zip(drawn, q, s):
        assert np.all(np.abs(np.array(at[:2]) - qi) <= 0.5e-4 + 1e-9)
        assert np.all(np.sign(np.array(at[:2]) - np.array(before[:2])) == si)


def test_target_ids_cannot_break_the_spel_program(robot):
    """Catches: a target id with a quote or a line break ending the Print string or the
    comment (ids come from the user's targets.csv)."""
    from vision_cal.program.spel import spel_program

    m = PlannedMark('a"b\nc', (10.0, 20.0), "target", (1, -1), ((7.0, 23.0),))
    text = spel_program(program_points([m]), robot, title="t\nx")
    p = parse_spel(text)
    drawn = drawn_marks(p["ops"], *robot.require_pen_heights())
    assert len(drawn) == 1 and drawn[0][1][:2] == (10.0, 20.0)
