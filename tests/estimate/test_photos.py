from types import SimpleNamespace as NS

import numpy as np

from tests.conftest import SM5, random_plan
from vision_cal.estimate.photos import per_photo_offsets
from vision_cal.model.robot import RobotModel


def _measurement(shift_photo=None, shift_mm=(0.0, 0.0), seed=0):
    rng = np.random.default_rng(seed)
    q, s = random_plan(40, rng)
    model = RobotModel(SM5)
    true = model.predict(q, s) + rng.normal(0, 0.01, (40, 2))  # robot repeatability
    ids = [f"m{i}" for i in range(40)]
    images = []
    for k in range(8):
        seen = rng.choice(40, 15, replace=False)
        dots = true[seen] + rng.normal(0, 0.005, (15, 2))
        if k == shift_photo:
            dots = dots + np.asarray(shift_mm)
        images.append(NS(file=f"img_{k}.png", status="ok", dots_xy_mm=dots,
                         dots_cov_mm2=np.tile(np.eye(2) * 0.005**2, (15, 1, 1))))
    marks = {i: NS(xy_mm=true[j]) for j, i in enumerate(ids)}
    return NS(marks=marks, images=images), model, dict(zip(ids, q)), dict(zip(ids, s))


def test_a_shifted_photo_is_flagged_and_sized():
    m, model, qd, sd = _measurement(shift_photo=3, shift_mm=(0.04, -0.03))
    out = per_photo_offsets(m, model, qd, sd)
    flagged = [o["file"] for o in out if o["flagged"]]
    assert flagged == ["img_3.png"]
    off = next(o for o in out if o["file"] == "img_3.png")["offset_mm"]
    np.testing.assert_allclose(off, [0.04, -0.03], atol=0.012)


def test_clean_photos_flag_nothing():
    for seed in range(5):
        out = per_photo_offsets(*_measurement(seed=seed))
        assert len(out) == 8 and not any(o["flagged"] for o in out)
