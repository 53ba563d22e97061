import numpy as np
import pytest

from tests.conftest import SM5
from vision_cal.dataset.csvio import read_plan, read_targets, write_plan, write_targets
from vision_cal.errors import VisionCalError
from vision_cal.model.robot import JointBacklash, JointCyclic, JointScale, RobotModel, SheetAffine
from vision_cal.plan.compensate import plan_targets

TRUE = RobotModel(SM5, (JointBacklash(joint=2, deg=0.12), JointScale(joint=1, scale=0.003),
                        JointCyclic(joint=2, harmonic=2, deg=0.05, phase_deg=20.0),
                        SheetAffine(((1.002, 0.0), (0.0, 1.0)))))


@pytest.mark.parametrize("approach", [(1, 1), (-1, 1), (1, -1)])
@pytest.mark.parametrize("elbow", [1, -1])
def test_commands_hit_targets_through_every_effect(approach, elbow):
    rng = np.random.default_rng(0)
    targets = np.column_stack([rng.uniform(-250, 100, 20), rng.uniform(-200, 150, 20)])
    planned = plan_targets(TRUE, [f"t{i}" for i in range(20)], targets, elbow=elbow,
                           approach=approach)
    ok = [p for p in planned if p.status == "ok"]
    assert len(ok) >= 15
    q = np.array([p.q_deg for p in ok])
    s = np.array([p.approach for p in ok], float)
    hit = TRUE.predict(q, s)
    np.testing.assert_allclose(hit, [p.target_mm for p in ok], atol=1e-6)


def test_ignoring_the_effects_misses():
    t = np.array([[50.0, -150.0]])
    p = plan_targets(RobotModel(SM5), ["o"], t)[0]
    miss = np.hypot(*(TRUE.predict([p.q_deg], [p.approach])[0] - t[0]))
    assert miss > 0.5  # 0.1 % gear scale, 0.12 deg backlash and 0.2 % shrink add up


def test_unreachable_and_limits_named_others_planned():
    t = np.array([[0.0, 0.0], [900.0, 0.0], [-424.26, -230.35]])
    p = plan_targets(RobotModel(SM5), ["a", "b", "c"], t)
    assert p[0].status == "ok"
    assert p[1].status == "failed" and "out of reach" in p[1].reason
    assert p[2].status == "failed" and "out of reach" in p[2].reason


def test_csv_round_trip_and_errors(tmp_path):
    write_targets(tmp_path / "t.csv", ["a", "b"], [[1.5, 2.0], [-3.0, 4.25]])
    ids, xy = read_targets(tmp_path / "t.csv")
    assert ids == ["a", "b"] and xy.tolist() == [[1.5, 2.0], [-3.0, 4.25]]
    planned = plan_targets(RobotModel(SM5), ids, xy + [0, -100])
    write_plan(tmp_path / "p.csv", [p.to_row() for p in planned])
    pid, q, s = read_plan(tmp_path / "p.csv")
    assert pid == ["a", "b"] and np.allclose(q, [p.q_deg for p in planned], atol=1e-5)
    (tmp_path / "bad.csv").write_text("id,x_mm,y_mm\na,1,zz\n")
    with pytest.raises(VisionCalError, match=r"bad.csv: line 2: y_mm: expected a number"):
        read_targets(tmp_path / "bad.csv")
    (tmp_path / "bad2.csv").write_text("id,x,y\n")
    with pytest.raises(VisionCalError, match="header lacks x_mm, y_mm"):
        read_targets(tmp_path / "bad2.csv")
