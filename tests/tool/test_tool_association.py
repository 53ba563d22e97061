"""Dots to marks at several j4_deg with the robot file's rough tool_mm (1.8 mm off here),
on a plan where the tool puts some marks beyond the tool-less model's reach: in one photo
of 48 marks (bench/tool_joint4.py render_case(4001), stored in data/) the association
swapped two marks 15 mm apart and refused four. It now predicts with a tool-less model that
reaches every mark, then again from the base model and tool fitted to the first pass:
every mark gets its own dot."""

import json
from pathlib import Path

import numpy as np

from vision_cal.config import DEFAULT
from vision_cal.dataset.session import load_session
from vision_cal.identify import associate as assoc
from vision_cal.identify.match import _tool_joints, _with_fitted_tool
from vision_cal.model.equivalent import equivalent_joints

DATA = json.loads((Path(__file__).parent / "data" / "joint4_association.json").read_text())


def _wrong(a, ids, dot_of):
    return [m for m, g in a.mark_to_group.items() if dot_of[g] != m]


def test_fitted_tool_association_swaps_no_marks(tmp_path):
    # measured_mm only lets the session load without a sheet; the association ignores it
    marks = [dict(m, measured_mm=DATA["truth_mm"][m["id"]]) for m in DATA["marks"]]
    (tmp_path / "session.json").write_text(json.dumps(
        {"format": "vision-cal/1", "robot": DATA["robot"], "marks": marks}))
    s = load_session(tmp_path)
    ids = [m.id for m in s.marks]
    rng = np.random.default_rng(0)
    order = rng.permutation(len(ids))
    dot_of = [ids[i] for i in order]
    groups = [assoc.DotGroup(np.array([DATA["truth_mm"][ids[i]]]) + rng.normal(0, 0.005, (1, 2)),
                             np.eye(2)[None] * 1e-4, (0,), (k,)) for k, i in enumerate(order)]
    images = [{0}] * len(ids)
    ac = DEFAULT.association
    kw = dict(max_zero_deg=ac.max_zero_deg, max_base_mm=ac.max_base_mm)
    # before: the robot file's tool-less model, commanded joints where it cannot reach the
    # mark (the tool puts it beyond L1 + L2): two marks 15 mm apart swapped
    eq = equivalent_joints(s.robot.params, s.robot.tool_mm, s.joints_deg, s.j4_deg)
    old = assoc.associate(np.where(np.isfinite(eq), eq, s.joints_deg), ids, images, groups,
                          s.robot.params, **kw)
    assert _wrong(old, ids, dot_of)
    # now: a tool-less model that reaches every mark (L2 + |tool|), then the fitted tool
    q, model = _tool_joints(s.robot.params, s.robot.tool_mm, s)
    first = assoc.associate(q, ids, images, groups, model, **kw)
    again = _with_fitted_tool(first, s, ids, images, groups, ac)
    assert not _wrong(first, ids, dot_of)          # the rough tool: a few refused, none wrong
    assert not _wrong(again, ids, dot_of) and len(again.mark_to_group) == len(ids)
