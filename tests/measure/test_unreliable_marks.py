"""A mark that cannot be trusted stays in calibration.json with its reason, out of the fit
(docs/format.md "Marks that could not be trusted"), and the report names it."""

from types import SimpleNamespace

import numpy as np

from vision_cal.config import DEFAULT
from vision_cal.dataset.session import load_session
from vision_cal.identify import marks as identify_marks
from vision_cal.identify.match import AssociatedDots
from vision_cal.identify.associate import DotGroup
from vision_cal.measure.types import MarkMeasurement, Measurement
from vision_cal.estimate.document import _unreliable_marks
from vision_cal.estimate.marks import collect_marks
from vision_cal.report.headline import mark_rows

from pathlib import Path

PAPER = Path(__file__).resolve().parents[2] / "fixtures" / "paper_sm5"


def _measurement(session, bad_id):
    marks = {}
    for m in session.marks:
        ok = m.id != bad_id
        marks[m.id] = MarkMeasurement(np.asarray(m.measured_mm, float), np.eye(2) * 1e-4, 2, 0.0,
                                      status="ok" if ok else "unreliable",
                                      reason="" if ok else "pen ink on printed ink (x axis)",
                                      printed_under="" if ok else "x axis")
    return Measurement(marks, [])


def test_an_unreliable_mark_is_kept_with_its_reason_and_not_fitted():
    session = load_session(PAPER)
    bad = session.marks[1].id
    meas = _measurement(session, bad)
    data, missing = collect_marks(session, meas)
    assert bad not in data.ids and bad not in missing
    assert len(data.ids) == len(session.marks) - 1
    marks = {k: {"measured_mm": [0, 0], "residual_mm": [0, 0]} for k in data.ids}
    notes = _unreliable_marks(marks, session, meas)
    assert marks[bad]["status"] == "unreliable"
    assert marks[bad]["reason"] == "pen ink on printed ink (x axis)"
    assert "residual_mm" not in marks[bad]
    assert notes == [f"1 mark(s) left out of the fit as unreliable: {bad} "
                            "(pen ink on printed ink (x axis))"]
    rows = {r["id"]: r for r in mark_rows({"marks": marks})}
    assert any("unreliable, left out of the fit" in f for f in rows[bad]["flags"])


def test_dots_that_cannot_be_trusted_are_no_height_evidence(monkeypatch):
    """The sheet's height is read from the marks' grid offsets: a dot flagged unreliable (ink
    beside it moves its centre, hence its offset) and a mark none of whose dots could be
    trusted give none (seed 4202 of bench/tool_joint4.py --render: the flagged mark had the
    largest height)."""
    seen = {}

    def heights(images, marks, groups_of, extent_mm, **kw):
        seen.update(groups_of)
        return {}, None, None

    monkeypatch.setattr(identify_marks, "sheet_heights", heights)
    images = [SimpleNamespace(dots_unreliable=("", "ink beside it", "")),
              SimpleNamespace(dots_unreliable=("", "", "ink beside it"))]
    groups = [DotGroup(np.zeros((2, 2)), np.zeros((2, 2, 2)), (0, 1), (0, 0)),
              DotGroup(np.zeros((2, 2)), np.zeros((2, 2, 2)), (0, 1), (1, 1)),
              DotGroup(np.zeros((1, 2)), np.zeros((1, 2, 2)), (1,), (2,))]
    marks = {"a": MarkMeasurement(np.zeros(2), np.eye(2), 2, 0.0),
             "b": MarkMeasurement(np.zeros(2), np.eye(2), 1, 0.0),
             "c": MarkMeasurement(np.zeros(2), np.eye(2), 1, 0.0, status="unreliable",
                                  reason="ink beside it")}
    dots = AssociatedDots(groups, SimpleNamespace(mark_to_group={"a": 0, "b": 1, "c": 2}),
                                [], None, [])
    session = SimpleNamespace(sheet=SimpleNamespace(extent_mm=(0, 0, 1, 1)))
    identify_marks.sheet_height_stage(session, images, marks, dots, None, DEFAULT)
    assert seen == {"a": [(0, 0), (1, 0)], "b": [(1, 1)]}
