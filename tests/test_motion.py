"""The approach-sign rule (the format's words, hand-computed) and its single owner."""

import numpy as np

from vision_cal.dataset.session import Mark, resolve_approach
from vision_cal.model.motion import approach_signs
from vision_cal.plan.calibration_plan import paper_plan


def test_approach_rule_by_hand():
    # home (0, 0) -> (10, 0): j1 +, j2 did not move: keeps the starting +1
    # -> (5, 0): j1 -, j2 still +1 -> (5, -3): j1 did not move: keeps -1; j2 -
    # -> (5, -3): nothing moved: both keep (-1, -1) -> (6, 2): (+1, +1)
    poses = [(10, 0), (5, 0), (5, -3), (5, -3), (6, 2)]
    expect = [(1, 1), (-1, 1), (-1, -1), (-1, -1), (1, 1)]
    np.testing.assert_array_equal(approach_signs(poses), expect)


def test_approach_from_home_and_given():
    # from home (20, 0) the move to (10, 0) is negative for j1
    np.testing.assert_array_equal(approach_signs([(10, 0)], home_deg=(20, 0)), [(-1, 1)])
    # a given sign replaces the rule and is kept by a joint that then does not move
    got = approach_signs([(10, 0), (10, 5), (10, 5)], given=[None, (-1, -1), None])
    np.testing.assert_array_equal(got, [(1, 1), (-1, -1), (-1, -1)])


def test_session_and_paper_plan_follow_the_rule():
    marks = [Mark("a", (10.0, 0.0)), Mark("b", (5.0, 0.0), approach=(1, -1)), Mark("c", (5.0, 0.0))]
    np.testing.assert_array_equal(resolve_approach(marks), [(1, 1), (1, -1), (1, -1)])
    plan = paper_plan()   # (0,0), (20,0), (-20,0), (0,60), (0,-60) from home (0, 0)
    assert [m.approach for m in plan] == [(1, 1), (1, 1), (-1, 1), (1, 1), (1, -1)]
