"""``locate --csv`` locates its pixels one height at a time (issue 41: 100,000 pixels of one
height were 100,000 calls; bench/speed.py): the same points as one pixel at a time, and the
first pixel whose ray misses its plane still named by its line."""

from __future__ import annotations

import numpy as np
import pytest

from tests.camera.test_fixed_unit import _entry
from vision_cal.actions.locate import _located
from vision_cal.camera.fixed import camera_from_json, locate
from vision_cal.errors import VisionCalError


def _where(line, column):
    return "px.csv", f"line {line}: {column}"


def _camera():
    e = _entry()
    e["dist"] = [-0.1, 0.05, 0.001, -0.001, 0.0]
    A = np.random.default_rng(1).normal(size=(7, 7)) * 1e-3
    e["covariance"] = {"matrix": (A @ A.T).tolist()}
    return camera_from_json(e)


def test_pixels_of_several_heights_are_located_as_one_at_a_time():
    cam = _camera()
    rng = np.random.default_rng(2)
    uv = rng.uniform([0, 0], [1199, 899], (30, 2))
    z = rng.choice([0.0, 25.0, -10.0], 30)
    got = _located(cam, uv, z, list(range(2, 32)), _where)
    for p, (u, v), zz in zip(got, uv, z):
        (one,) = locate(cam, [[u, v]], zz)
        assert p.z_mm == zz and p.pixel == one.pixel
        for a, b in ((p.robot_mm, one.robot_mm), (p.sheet_mm, one.sheet_mm),
                     (p.robot_std_mm, one.robot_std_mm)):
            assert np.allclose(a, b, rtol=1e-12, atol=1e-12)


def test_the_first_pixel_whose_ray_misses_its_plane_is_named_by_its_line():
    """The camera is 800 mm up: a height of 900 mm is behind it (lines 3 and 5 of four)."""
    cam = _camera()
    uv = np.array([[10.0, 20.0], [30.0, 40.0], [50.0, 60.0], [70.0, 80.0]])
    with pytest.raises(VisionCalError) as e:
        _located(cam, uv, [0.0, 900.0, 0.0, 900.0], [2, 3, 4, 5], _where)
    assert e.value.field == "line 3: z_mm" and "900" in str(e.value)
