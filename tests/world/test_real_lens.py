"""The synthetic world's lens beyond k1 k2 (issue 28 section 3): scene files take OpenCV's
8/12/14-term models, ``camera.phone_lens`` builds tangential and thin-prism terms of a
given size in pixels, and the photo's lens puts a point where ``cv2.projectPoints`` with
those 12 terms puts it (no pyrender: ``distort_image`` on a drawn image)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from vision_cal.errors import VisionCalError
from vision_cal.world.camera import distort_image
from vision_cal.world.camera import corner_shift as _corner_shift, phone_lens
from vision_cal.world.scene import scene_from_dict

SIZE = (800, 600)
F = 700.0


def test_scene_takes_twelve_lens_terms_and_refuses_seven():
    d12 = list(phone_lens(f_px=F, size_px=SIZE, k1=-0.05, rng=1))
    sc = scene_from_dict({"camera": {"dist": d12, "declared": False}})
    assert sc.camera.dist == pytest.approx(tuple(d12))
    with pytest.raises(VisionCalError, match="camera.dist"):
        scene_from_dict({"camera": {"dist": d12[:7]}})


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_phone_lens_terms_have_the_size_asked(seed):
    d = np.array(phone_lens(f_px=F, size_px=SIZE, tangential_px=1.5, prism_px=2.5, rng=seed))
    x, y = SIZE[0] / 2 / F, SIZE[1] / 2 / F
    tang, prism = d.copy(), d.copy()
    tang[[0, 1]] = 0
    tang[8:] = 0
    prism[:8] = 0
    assert F * _corner_shift(tang, x, y) == pytest.approx(1.5, rel=1e-6)
    assert F * _corner_shift(prism, x, y) == pytest.approx(2.5, rel=1e-6)
    # the default: PHONE_*_PX per 1000 px of half-diagonal (0.6 px each): 0.3 px here
    d0 = np.array(phone_lens(f_px=F, size_px=SIZE, rng=seed))
    t0 = d0.copy()
    t0[:2] = 0
    t0[8:] = 0
    assert F * _corner_shift(t0, x, y) == pytest.approx(0.6 * 500 / 1000, rel=1e-6)


def test_the_photo_lens_puts_points_where_opencv_projects_them():
    """Dots drawn in an ideal image, distorted with 12 terms (k1 -0.08, tangential 4 px,
    prism 6 px at the corner): their centroids within 0.05 px of cv2.projectPoints."""
    K = np.array([[F, 0, (SIZE[0] - 1) / 2 + 7], [0, F, (SIZE[1] - 1) / 2 - 5], [0, 0, 1]])
    dist = np.array(phone_lens(f_px=F, size_px=SIZE, k1=-0.08, k2=0.02, tangential_px=4.0,
                               prism_px=6.0, rng=3))
    pts = np.array([[u, v] for u in (90.0, 400.0, 700.0) for v in (80.0, 300.0, 520.0)])
    img = np.zeros((SIZE[1], SIZE[0]), np.float32)
    V, U = np.mgrid[0:SIZE[1], 0:SIZE[0]]
    for u, v in pts:
        img += np.exp(-((U - u) ** 2 + (V - v) ** 2) / (2 * 2.0 ** 2))
    out = distort_image(img, K=K, dist=dist)
    xn = np.c_[(pts - K[:2, 2]) / F, np.ones(len(pts))]
    want = cv2.projectPoints(xn, np.zeros(3), np.zeros(3), K, dist)[0].reshape(-1, 2)
    moved = np.linalg.norm(want - pts, axis=1)
    assert moved.max() > 5.0        # the lens does move them
    for w in want:
        u0, v0 = np.round(w).astype(int)
        win = out[v0 - 9:v0 + 10, u0 - 9:u0 + 10].astype(float)
        vv, uu = np.mgrid[v0 - 9:v0 + 10, u0 - 9:u0 + 10]
        c = np.array([(win * uu).sum(), (win * vv).sum()]) / win.sum()
        assert np.linalg.norm(c - w) < 0.05, (c, w)
