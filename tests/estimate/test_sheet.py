"""A smooth residual over the sheet is a sheet effect; white noise and backlash are not."""

import numpy as np

from vision_cal.estimate.sheet import smooth_residual

EXT = (-297.0, -210.0, 297.0, 210.0)


def _marks(n=38, seed=0):
    rng = np.random.default_rng(seed)
    return rng, rng.uniform([-260, -180], [260, 180], (n, 2))


def test_smooth_field_is_reported_with_a_map():
    rng, xy = _marks()
    # the parallax of a 0.6 mm bump seen from 700 mm: up to ~0.05 mm, smooth over the sheet
    z = 0.6 * np.exp(-np.sum((xy - [60, 40]) ** 2, axis=1) / (2 * 70.0**2))
    field = z[:, None] * (xy - [100.0, -150.0]) / 700.0
    out = smooth_residual(xy, field + rng.normal(0, 0.01, xy.shape), EXT)
    assert out is not None and out["kind"] == "sheet"
    assert np.asarray(out["map"]["dx_mm"]).shape == (len(out["map"]["y_mm"]),
                                                     len(out["map"]["x_mm"]))


def test_noise_and_backlash_are_not_a_sheet_effect():
    hits = 0
    for seed in range(20):
        rng, xy = _marks(seed=seed)
        white = rng.normal(0, 0.01, xy.shape)
        # backlash: a fixed joint-space offset whose sign flips with the approach side
        sign = rng.choice([-1.0, 1.0], size=(len(xy), 1))
        backlash = 0.03 * sign * np.array([[0.6, 0.8]]) + rng.normal(0, 0.01, xy.shape)
        hits += smooth_residual(xy, white, EXT, rng=seed) is not None
        hits += smooth_residual(xy, backlash, EXT, rng=seed) is not None
    assert hits <= 1        # alpha = 1e-3 over 40 tries: expect 0.04 false claims
