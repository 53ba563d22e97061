"""measurement.json is the measurement, whole: ``Measurement.from_json`` gives back what
``measure_folder`` returned, and it carries what the report draws (marker ids and corners,
each dot's pixel and the mark it was taken for)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from tests.measure import synth_measure as sm
from vision_cal.dataset.session import load_session
from vision_cal.actions.measure_folder import measure_folder
from vision_cal.measure.height import HeightMap, MarkHeight
from vision_cal.measure.mapping import LensEstimate, SheetMapping
from vision_cal.measure.types import ImageResult, Measurement


def _same(a, b, where="") -> None:
    """Equal field by field (arrays to the bit, NaN equal to NaN)."""
    if dataclasses.is_dataclass(a):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            _same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), where
        for k in a:
            _same(a[k], b[k], f"{where}[{k}]")
    elif isinstance(a, (list, tuple)) and not (a and isinstance(a[0], (int, float))):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{where}[{i}]")
    elif a is None or isinstance(a, (str, bool)):
        assert a == b, f"{where}: {a!r} != {b!r}"
    else:
        x, y = np.asarray(a, float), np.asarray(b, float)
        assert x.shape == y.shape and np.array_equal(x, y, equal_nan=True), where


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("mj")
    sheet = sm.small_sheet()
    targets = sm.free_targets(sheet, 6, rng=5, box=(85.0, 62.0))
    q = sm.plan_for(targets)
    tex = sm.texture(sheet, targets, rng=1)
    src = tmp / "in"
    src.mkdir()
    for i, (tilt, az) in enumerate(((10.0, 60.0), (14.0, -70.0))):
        K, T = sm.view(tilt_deg=tilt, azimuth_deg=az)
        sm.write_png(src / f"p{i}.png", sm.photo(sheet, tex, K=K, T=T, rng=2 + i))
    (src / "blank.png").write_bytes(b"not an image")
    ids = [f"c{i}" for i in range(len(targets))]
    files = ["p0.png", "blank.png", "p1.png"]
    sm.write_session(src, sm.session_json(sheet, marks=list(zip(ids, q)),
                                          images=[(f, ids) for f in files], robot=sm.NOMINAL))
    meas = measure_folder(load_session(src), out_dir=tmp / "out", jobs=1)
    return meas, json.loads((tmp / "out" / "measurement.json").read_text())


def test_measurement_json_reads_back_to_the_same_measurement(measured):
    meas, doc = measured
    assert doc["format"] == "vision-cal/measurement/1"
    back = Measurement.from_json(doc)
    _same(meas, back)
    assert [im.status for im in back.images] == ["ok", "skipped", "ok"]
    assert back.images[0].mapping is not None and len(back.marks) == 6


def test_measurement_json_carries_what_the_report_draws(measured):
    meas, doc = measured
    im = doc["images"][0]
    assert im["size_px"] == list(meas.images[0].size_px)
    assert len(im["marker_ids"]) == len(im["markers_px"]) > 0
    assert np.asarray(im["markers_px"]).shape[1:] == (4, 2)
    dots = im["dots"]
    assert len(dots["uv_px"]) == len(dots["mark"]) == meas.images[0].n_dots
    # each dot is named by the mark association took it for, and only those
    named = {m for m in dots["mark"] if m}
    assert named and named <= set(meas.marks)
    for k, mid in enumerate(dots["mark"]):
        if mid:
            assert "p0.png" in meas.marks[mid].files
            assert np.hypot(*(np.asarray(dots["xy_mm"][k]) - meas.marks[mid].xy_mm)) < 0.5


def test_the_parts_round_trip_alone():
    m = SheetMapping(np.eye(3) * 2.0, np.eye(3), np.arange(5.0), 0.1, 0.01, 16,
                     np.eye(8), np.eye(3), np.eye(3) * 3)
    _same(m, SheetMapping.from_json(json.loads(json.dumps(m.to_json()))))
    lens = LensEstimate(True, "k1k2", np.eye(3), np.arange(5.0), (640, 480), 1.0, 0.5, 0.1,
                        0.05, 1.1, 0.6, 4, {"k1": 0.6}, -1)
    _same(lens, LensEstimate.from_json(json.loads(json.dumps(lens.to_json()))))
    h = MarkHeight(0.2, 0.01, 3, "parallax", np.array([1.0, 2.0]), np.eye(2) * 1e-4)
    _same(h, MarkHeight.from_json(json.loads(json.dumps(h.to_full_json()))))
    hm = HeightMap(np.arange(3.0), np.arange(2.0), np.full((2, 3), 0.125),
                   np.full((2, 3), 0.25), 50.0, 0.1, 12.0, 5, 0.03, 0.2, True,
                   {"a": {"xy_mm": [1.0, 2.0], "height_mm": 0.1, "height_std_mm": 0.01}})
    _same(hm, HeightMap.from_json(json.loads(json.dumps(hm.to_json()))))
    im = ImageResult("x.png", "skipped", "blank image: no contrast", size_px=(10, 20))
    _same(im, ImageResult.from_json(json.loads(json.dumps(im.to_json()))))
