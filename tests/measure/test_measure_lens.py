"""An undeclared lens is found from the marker grid (and only when there is one)."""

from __future__ import annotations

import json

import numpy as np

from tests.measure import synth_measure as sm
from vision_cal.dataset.session import load_session
from vision_cal.actions.measure_folder import measure_folder

VIEWS = [dict(tilt_deg=12.0, azimuth_deg=20.0), dict(tilt_deg=18.0, azimuth_deg=150.0),
         dict(tilt_deg=8.0, azimuth_deg=-100.0)]


def _dataset(folder, *, dist, rng=0):
    sheet = sm.small_sheet()
    targets = sm.free_targets(sheet, 12, rng=rng + 5, box=(85.0, 62.0))
    q = sm.plan_for(targets)
    tex = sm.texture(sheet, targets, rng=rng)
    ids = [f"c{i:02d}" for i in range(len(targets))]
    images = []
    for k, v in enumerate(VIEWS):
        K, T = sm.view(**v)
        sm.write_png(folder / f"p{k}.png", sm.photo(sheet, tex, K=K, T=T, dist=dist,
                                                      rng=rng + 10 + k))
        images.append((f"p{k}.png", ids))
    sm.write_session(folder, sm.session_json(sheet, marks=list(zip(ids, q)), images=images,
                                             robot=sm.NOMINAL))
    return load_session(folder), dict(zip(ids, targets))


def _errors(meas, truth):
    e = np.array([meas.marks[k].xy_mm - truth[k] for k in meas.marks])
    sd = np.array([meas.marks[k].std_mm for k in meas.marks])
    return e, sd


def test_undeclared_lens_is_reported_and_accuracy_kept(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    dist = [-0.14, 0.05, 0.0, 0.0, 0.0]
    s, truth = _dataset(src, dist=dist, rng=1)
    meas = measure_folder(s, out_dir=tmp_path / "out", jobs=1)
    assert all(im.status == "ok" for im in meas.images), meas.images_json()
    lens = meas.lens
    assert lens is not None and lens.kept
    assert lens.rms_px_after < 0.5 * lens.rms_px_before
    assert lens.cv_rms_px_after < lens.cv_rms_px_before
    eff = meas.effects_json()
    assert [e["name"] for e in eff] == ["lens_distortion"]
    assert eff[0]["coefficients"][0] < -0.05            # barrel, as injected
    json.dumps(meas.to_json())
    e, sd = _errors(meas, truth)
    assert len(e) >= 10
    rms = float(np.sqrt(np.mean(np.sum(e**2, axis=1))))
    assert rms < 0.015, rms
    z = float(np.sqrt(np.mean((e / sd) ** 2)))
    assert 0.4 < z < 2.0, z
    assert all(meas.marks[k].n_photos == 3 for k in meas.marks)


def test_straight_lens_claims_no_distortion(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    s, truth = _dataset(src, dist=None, rng=2)
    meas = measure_folder(s, out_dir=tmp_path / "out", jobs=1)
    assert meas.lens is not None and not meas.lens.kept
    assert meas.effects_json() == []
    e, _ = _errors(meas, truth)
    assert np.sqrt(np.mean(np.sum(e**2, axis=1))) < 0.015
