"""A photo whose dots all sit a millimetre from where the other photos see them is left out,
not the marks it shares with them (issue 18 section 4)."""

from __future__ import annotations

import numpy as np

from tests.measure import synth_measure as sm
from vision_cal.dataset.session import load_session
from vision_cal.actions.measure_folder import measure_folder

def _run(tmp_path, shift_mm):
    src = tmp_path / "in"
    ids, targets = sm.shifted_series(src, moved_photo=2, shift_mm=shift_mm)
    meas = measure_folder(load_session(src), out_dir=tmp_path / "out", jobs=1)
    return meas, dict(zip(ids, targets))


def test_the_photo_is_left_out_not_its_marks(tmp_path):
    meas, truth = _run(tmp_path, (0.8, -0.6))
    st = {im.file: (im.status, im.reason or "") for im in meas.images}
    assert st["p2.png"][0] == "skipped" and "disagrees with the other photos" in st["p2.png"][1]
    assert "1.00 mm" in st["p2.png"][1]
    assert all(st[f][0] == "ok" for f in ("p0.png", "p1.png", "p3.png"))
    assert set(meas.marks) == set(truth) and not meas.refused
    e = np.array([meas.marks[k].xy_mm - truth[k] for k in truth])
    assert np.abs(e).max() < 0.03


def test_photos_that_agree_are_all_kept(tmp_path):
    meas, truth = _run(tmp_path, (0.0, 0.0))
    assert all(im.status == "ok" for im in meas.images)
    assert set(meas.marks) == set(truth)
