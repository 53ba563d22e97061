"""A dot is refined in a configured number of photos, not in every photo that shows it
(issue 33): the count, and the checks that still see the dots only seen."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from vision_cal.config import DEFAULT, PlanMatchConfig
from vision_cal.errors import CalibrationError
from vision_cal.measure.photo_agreement import disagreeing_photos
from vision_cal.measure.plan_match import check_plan_match
from vision_cal.measure.views import ViewCount


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
