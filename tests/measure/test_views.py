"""A dot is refined in a configured number of photos, not in every photo that shows it
(issue 33): the count, and the checks that still see the dots only seen."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from tests.measure import synth_measure as sm
from vision_cal.config import DEFAULT, PlanMatchConfig
from vision_cal.dataset.session import load_session
from vision_cal.errors import CalibrationError
from vision_cal.identify.associate import DotGroup, combine
from vision_cal.measure.photo_agreement import disagreeing_photos
from vision_cal.measure.types import ImageResult
from vision_cal.identify.plan_match import check_plan_match
from vision_cal.measure.views import ViewCount
from vision_cal.actions.measure_folder import measure_folder


def test_a_dot_is_wanted_until_it_has_its_reliable_views():
    v = ViewCount(2, tol_mm=0.5)
    a, b = np.array([10.0, 20.0]), np.array([40.0, -5.0])
    assert v.wanted([a, b]).all()
    v.add([a, b], [True, False])          # b unreliable: does not count
    assert v.wanted([a, b]).all()
    v.add([a + 0.2, b], [True, True])     # the same dot, moved within the tolerance
    assert v.wanted([a + 0.1, b]).tolist() == [False, True]
    assert v.wanted([a + 0.7]).tolist() == [True]   # beyond the tolerance: another dot
    v.add([b], [True])
    assert not v.wanted([b]).any()


def test_a_new_camera_place_refines_the_dot_again():
    v = ViewCount(1, tol_mm=0.5, place_fraction=0.02)
    a = np.array([[10.0, 20.0]])
    here = v.place([0.0, 0.0, 700.0])
    assert v.place([5.0, 0.0, 700.0]) == here          # 5 mm at 700 mm: the same place
    there = v.place([100.0, 0.0, 700.0])
    assert there != here and v.place(None) == -1
    v.add(a, [True], here)
    assert not v.wanted(a, here).any()
    assert v.wanted(a, there).all()                     # its parallax needs this view
    v.add(a, [True], there)
    assert not v.wanted(a, there).any()


def test_zero_views_refines_every_dot():
    v = ViewCount(0, tol_mm=0.5)
    v.add([[1.0, 1.0]] * 5, [True] * 5)
    assert v.wanted([[1.0, 1.0]]).all()


def test_the_default_is_a_few_views():
    assert 1 <= DEFAULT.dots.views_per_dot <= 10


def _im(xy, seen=()):
    xy = np.asarray(xy, float).reshape(-1, 2)
    return SimpleNamespace(status="ok", dots_xy_mm=xy, n_dots=len(xy),
                           seen_xy_mm=np.asarray(seen, float).reshape(-1, 2))


def test_a_photo_of_seen_dots_only_moved_as_a_whole_is_found():
    rng = np.random.default_rng(3)
    marks = rng.uniform(-80, 80, (8, 2))
    ims = [_im(marks + rng.normal(0, 0.005, marks.shape)) for _ in range(3)]
    ims.append(_im((), seen=marks + [0.6, -0.4]))   # nothing refined: its dots only seen
    assert list(disagreeing_photos(ims)) == [3]
    ims[3] = _im((), seen=marks + rng.normal(0, 0.03, marks.shape))
    assert disagreeing_photos(ims) == {}


def test_seen_dots_count_when_a_photo_shows_far_more_dots_than_marks():
    cfg = PlanMatchConfig()
    n = int(cfg.max_dots_per_mark * 2 + cfg.spare_dots + 1)
    ims = [_im(np.zeros((1, 2)), seen=np.zeros((n - 1, 2))) for _ in range(3)]
    with pytest.raises(CalibrationError, match=f"show {n} dots"):
        check_plan_match("s.json", ["a", "b", "c"], ims, [("m1", "m2")] * 3, n, 2, cfg)
    ims = [_im(np.zeros((1, 2)), seen=np.zeros((1, 2))) for _ in range(3)]
    check_plan_match("s.json", ["a", "b", "c"], ims, [("m1", "m2")] * 3, 2, 2, cfg)


def _series(tmp_path, views_per_dot, shift_first_mm=(0.0, 0.0)):
    """Four photos of the same ten marks (photo 0 moved as a whole by ``shift_first_mm``),
    measured with ``views_per_dot``."""
    src = tmp_path / "in"
    ids, targets = sm.shifted_series(src, moved_photo=0, shift_mm=shift_first_mm)
    cfg = replace(DEFAULT, dots=replace(DEFAULT.dots, views_per_dot=views_per_dot))
    meas = measure_folder(load_session(src), out_dir=tmp_path / "out", jobs=1, config=cfg)
    return meas, dict(zip(ids, targets))


def test_each_mark_is_refined_in_its_views_and_seen_in_the_rest(tmp_path):
    meas, truth = _series(tmp_path, 2)
    assert set(meas.marks) == set(truth) and not meas.refused
    n_dots = [im.n_dots for im in meas.images]
    n_seen = [len(im.seen_xy_mm) for im in meas.images]
    assert n_dots == [10, 10, 0, 0] and n_seen == [0, 0, 10, 10]
    for mid, m in meas.marks.items():
        assert m.n_photos == 2 and m.files == ("p0.png", "p1.png")
        # the mark's covariance is the one of the two views used, not of four
        ks = [0, 1]
        js = [list(meas.images[k].dots_mark).index(mid) for k in ks]
        flat = m.reference == "markers (sheet flat)"   # the marker mapping's centres
        xy_f, cov_f = ("dots_global_xy_mm", "dots_global_cov_mm2") if flat else (
            "dots_xy_mm", "dots_cov_mm2")
        g = DotGroup(np.array([getattr(meas.images[k], xy_f)[j] for k, j in zip(ks, js)]),
                     np.array([getattr(meas.images[k], cov_f)[j] for k, j in zip(ks, js)]),
                     tuple(ks), tuple(js))
        assert np.allclose(m.cov_mm2, combine(g)[1], rtol=1e-9)
        e = m.xy_mm - truth[mid]
        assert float(e @ np.linalg.solve(m.cov_mm2, e)) < 25.0   # within 5 std (2-D)
    # the seen dots are where the refined ones are, well within the grouping tolerance
    seen = meas.images[3].seen_xy_mm
    ref = meas.images[0].dots_xy_mm
    d = np.linalg.norm(seen[:, None] - ref[None], axis=2).min(axis=1)
    assert d.max() < 0.1
    back = ImageResult.from_json(meas.images[3].to_json())
    assert np.array_equal(back.seen_xy_mm, seen)


def test_a_photo_left_out_gives_its_views_to_the_others(tmp_path):
    # moved beyond photo_agreement.max_offset_mm, within the grouping tolerance: its dots
    # are the others' dots, which it alone was refined in
    meas, truth = _series(tmp_path, 1, shift_first_mm=(0.3, -0.2))
    st = {im.file: im.status for im in meas.images}
    assert st["p0.png"] == "skipped" and set(st.values()) == {"skipped", "ok"}
    assert set(meas.marks) == set(truth)
    for mid, m in meas.marks.items():
        assert m.files == ("p1.png",)
        assert np.abs(m.xy_mm - truth[mid]).max() < 0.03
