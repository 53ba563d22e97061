"""A mark that cannot be trusted stays in calibration.json with its reason, out of the fit
(docs/format.md "Marks that could not be trusted"), and the report names it."""

import numpy as np

from vision_cal.dataset.session import load_session
from vision_cal.measure.batch import Measurement, MarkMeasurement
from vision_cal.pipeline import _unreliable_marks, collect_marks
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
