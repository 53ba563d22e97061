"""A printed grid that is not where sheet.grid declares it (issue 18 section 2): named in
one line with sheet.grid.origin_mm and the offset seen, the marks measured against the
markers (not shifted by the offset, not taken for a sheet height)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.measure import synth_measure as sm
from vision_cal.dataset.session import load_session
from vision_cal.measure.batch import measure_folder

N = 8


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    sheet = sm.small_sheet()
    targets = sm.free_targets(sheet, N, rng=41, box=(85.0, 62.0))
    q = sm.plan_for(targets)
    views = [sm.view(tilt_deg=12.0, azimuth_deg=30.0), sm.view(tilt_deg=16.0, azimuth_deg=-110.0)]
    tex = sm.texture(sheet, targets, rng=3)
    photos = [sm.photo(sheet, tex, K=K, T=T, rng=70 + k) for k, (K, T) in enumerate(views)]
    return sheet, targets, q, photos


def _measure(tmp_path, world, origin_mm):
    sheet, targets, q, photos = world
    ids = [f"c{i}" for i in range(N)]
    src = tmp_path / "in"
    src.mkdir()
    d = sm.session_json(sheet, marks=list(zip(ids, q)),
                        images=[(f"p{k}.png", ids) for k in range(len(photos))], robot=sm.NOMINAL)
    d["sheet"]["grid"]["origin_mm"] = list(origin_mm)
    sm.write_session(src, d)
    for k, img in enumerate(photos):
        sm.write_png(src / f"p{k}.png", img)
    meas = measure_folder(load_session(src), out_dir=tmp_path / "out", jobs=1)
    err = np.array([meas.marks[i].xy_mm - t for i, t in zip(ids, targets)])
    return meas, err


@pytest.mark.parametrize("origin", [(0.0, 0.5), (0.3, 0.0)])
def test_a_misdeclared_grid_is_named_and_the_markers_measure(tmp_path, world, origin):
    meas, err = _measure(tmp_path, world, origin)
    said = [w for w in meas.warnings if w.startswith("sheet.grid.origin_mm")]
    print(said, np.abs(err).max())
    assert len(said) == 1 and "a wrong declaration" in said[0]
    # the origin it suggests is the printed one (0, 0), modulo the 1 mm pitch
    import re

    sx, sy = (float(v) for v in re.search(r"declare origin_mm \[(\S+), (\S+)\]",
                                          said[0]).groups())
    assert abs(sx - round(sx)) < 0.02 and abs(sy - round(sy)) < 0.02
    assert len(meas.marks) == N
    assert np.abs(err).max() < 0.05          # against the markers: not 0.3-0.5 mm off
    assert all(m.reference.startswith("markers") for m in meas.marks.values())


def test_a_grid_where_it_is_declared_says_nothing(tmp_path, world):
    meas, err = _measure(tmp_path, world, (0.0, 0.0))
    assert not any(w.startswith("sheet.grid.origin_mm") for w in meas.warnings)
    assert any(m.reference == "grid" or m.reference.startswith("markers")
               for m in meas.marks.values())
