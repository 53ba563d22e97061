"""Camera poses, projection and lens distortion of a render."""

import cv2
import numpy as np
import pytest

from vision_cal.errors import VisionCalError
from vision_cal.world.camera import (_undistort_maps, camera_matrix, default_views,
                                      distort_image, look_at, project)
from vision_cal.world.sheet import make_sheet


def test_camera_matrix_centres_the_principal_point():
    K = camera_matrix(size_px=(640, 480), f_px=500.0)
    np.testing.assert_allclose(K, [[500, 0, 319.5], [0, 500, 239.5], [0, 0, 1]])


def test_look_at_straight_down_keeps_the_sheet_upright():
    K = camera_matrix(size_px=(640, 480), f_px=500.0)
    T = look_at(eye_mm=(10.0, 20.0, 1000.0), target_mm=(10.0, 20.0))
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
    assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0)
    uv = project([[10.0, 20.0], [110.0, 20.0], [10.0, 120.0]], K=K, T_cam_sheet=T)
    np.testing.assert_allclose(uv[0], K[:2, 2], atol=1e-9)         # target on the axis
    np.testing.assert_allclose(uv[1] - uv[0], [50.0, 0.0], atol=1e-9)   # +x right
    np.testing.assert_allclose(uv[2] - uv[0], [0.0, -50.0], atol=1e-9)  # +y up
    with pytest.raises(VisionCalError):
        look_at(eye_mm=(0, 0, 100), target_mm=(0, 0, 0), up_hint=(0, 0, 1))


def test_project_matches_the_pinhole_formula_and_distortion():
    rng = np.random.default_rng(0)
    K = camera_matrix(size_px=(800, 600), f_px=700.0)
    T = look_at(eye_mm=(-200.0, 150.0, 900.0), target_mm=(30.0, -20.0), up_hint=(0.3, 1, 0))
    xy = rng.uniform(-200, 200, (20, 2))
    pc = (T @ np.column_stack([xy, np.zeros(20), np.ones(20)]).T).T[:, :3]
    uv_ref = pc[:, :2] / pc[:, 2:] @ K[:2, :2].T + K[:2, 2]
    np.testing.assert_allclose(project(xy, K=K, dist=None, T_cam_sheet=T), uv_ref, atol=1e-9)
    d = np.array([-0.1, 0.02, 0.0, 0.0, 0.0])
    x = pc[:, :2] / pc[:, 2:]
    r2 = np.sum(x * x, axis=1, keepdims=True)
    uv_d = x * (1 + d[0] * r2 + d[1] * r2 ** 2) @ K[:2, :2].T + K[:2, 2]
    np.testing.assert_allclose(project(xy, K=K, dist=d, T_cam_sheet=T), uv_d, atol=1e-9)


def test_default_views_keep_the_sheet_in_frame_and_tilt_as_asked():
    sheet = make_sheet()
    K = camera_matrix(size_px=(2000, 1500), f_px=1800.0)
    views = default_views(sheet, n=12, size_px=(2000, 1500), K=K, tilt_deg=(10, 25), rng=4)
    x0, y0, x1, y1 = sheet.extent_mm
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    tilts = []
    for T in views:
        uv = project(corners, K=K, T_cam_sheet=T)
        assert np.all(uv >= 0) and np.all(uv[:, 0] <= 1999) and np.all(uv[:, 1] <= 1499)
        # as close as it can be: a corner touches the central 92 % of the frame
        lo, hi = np.array([80.0, 60.0]) - 0.5, np.array([1920.0, 1440.0]) - 0.5
        assert min(np.min(uv - lo), np.min(hi - uv)) == pytest.approx(0.0, abs=0.5)
        tilts.append(np.degrees(np.arccos(-T[2, 2])))   # optical axis vs straight down
    assert min(tilts) >= 10 - 1e-6 and max(tilts) <= 25 + 1e-6
    assert max(tilts) - min(tilts) > 5     # they differ


def _blobs(size_px, centres_px, sigma=1.8):
    """Sum of Gaussian blobs (float32 image in 0..200) at given pixel centres."""
    w, h = size_px
    img = np.zeros((h, w), np.float32)
    for u, v in centres_px:
        u0, v0 = int(round(u)), int(round(v))
        r = int(5 * sigma) + 1
        vv, uu = np.mgrid[v0 - r:v0 + r + 1, u0 - r:u0 + r + 1]
        img[v0 - r:v0 + r + 1, u0 - r:u0 + r + 1] += 200 * np.exp(
            -((uu - u) ** 2 + (vv - v) ** 2) / (2 * sigma ** 2))
    return img


def _centroids(img, guesses, r=7):
    out = []
    for u, v in guesses:
        u0, v0 = int(round(u)), int(round(v))
        win = img[v0 - r:v0 + r + 1, u0 - r:u0 + r + 1].astype(float)
        vv, uu = np.mgrid[v0 - r:v0 + r + 1, u0 - r:u0 + r + 1]
        out.append([np.sum(win * uu) / win.sum(), np.sum(win * vv) / win.sum()])
    return np.array(out)


@pytest.mark.parametrize("dist", [[-0.1, 0.0, 0.0, 0.0, 0.0],
                                  [0.08, -0.05, 0.002, -0.001, 0.01]])
def test_distort_image_puts_points_where_project_points_does(dist):
    size = (640, 480)
    K = camera_matrix(size_px=size, f_px=600.0)
    T = look_at(eye_mm=(40.0, -30.0, 700.0), target_mm=(0.0, 0.0), up_hint=(0.1, 1, 0))
    g = np.arange(-240.0, 241.0, 40.0)
    xy = np.stack(np.meshgrid(g, np.arange(-160.0, 161.0, 40.0)), -1).reshape(-1, 2)
    ideal = project(xy, K=K, T_cam_sheet=T)
    real = project(xy, K=K, dist=dist, T_cam_sheet=T)
    keep = np.all((real > 12) & (real < np.array(size) - 13), axis=1) & \
        np.all((ideal > 12) & (ideal < np.array(size) - 13), axis=1)
    assert keep.sum() > 60
    img = _blobs(size, ideal[keep])
    out = distort_image(img, K=K, dist=dist)
    # the blobs moved by up to several pixels, and land where projectPoints says
    assert np.abs(real[keep] - ideal[keep]).max() > 2.0
    err = _centroids(out, real[keep]) - real[keep]
    # the blob is distorted with the lens (not symmetric), so its centroid is off by the
    # local second-order term of the distortion: a few thousandths of a pixel
    assert np.abs(err).max() < 0.02


def test_distort_image_with_a_wider_ideal_camera():
    size = (320, 240)
    K = camera_matrix(size_px=size, f_px=300.0)
    K_ideal = camera_matrix(size_px=size, f_px=260.0)
    dist = np.array([-0.15, 0.0, 0.0, 0.0, 0.0])
    T = look_at(eye_mm=(0.0, 0.0, 500.0), target_mm=(0.0, 0.0))
    xy = np.stack(np.meshgrid(np.arange(-200.0, 201, 50), np.arange(-150.0, 151, 50)), -1)
    xy = xy.reshape(-1, 2)
    ideal = project(xy, K=K_ideal, T_cam_sheet=T)
    real = project(xy, K=K, dist=dist, T_cam_sheet=T)
    keep = np.all((real > 12) & (real < np.array(size) - 13), axis=1)
    out = distort_image(_blobs(size, ideal), K=K, dist=dist, K_ideal=K_ideal)
    np.testing.assert_allclose(_centroids(out, real[keep]), real[keep], atol=0.03)


def test_distort_image_without_distortion_is_the_identity():
    img = (np.arange(48 * 64 * 3) % 251).astype(np.uint8).reshape(48, 64, 3)
    K = camera_matrix(size_px=(64, 48), f_px=80.0)
    np.testing.assert_array_equal(distort_image(img, K=K, dist=None), img)
    np.testing.assert_array_equal(distort_image(img, K=K, dist=np.zeros(5)), img)


def test_lens_maps_match_undistort_points_per_pixel():
    K = camera_matrix(size_px=(900, 700), f_px=700.0)
    d = np.array([-0.12, 0.03, 0.001, -0.0007, -0.004])
    mx, my = _undistort_maps((900, 700), K.tobytes(), d.tobytes(), K.tobytes())
    rng = np.random.default_rng(3)
    uv = np.column_stack([rng.integers(0, 900, 3000), rng.integers(0, 700, 3000)])
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    exact = cv2.undistortPoints(uv.astype(float).reshape(-1, 1, 2), K, d, P=K,
                                criteria=crit).reshape(-1, 2)
    got = np.column_stack([mx[uv[:, 1], uv[:, 0]], my[uv[:, 1], uv[:, 0]]])
    assert np.abs(got - exact).max() < 2e-4
    # and the map inverts projectPoints' distortion: re-distorting lands on the pixel
    x = np.column_stack([(got - K[:2, 2]) / 700.0, np.ones(len(got))])
    back, _ = cv2.projectPoints(x, np.zeros(3), np.zeros(3), K, d)
    assert np.abs(back.reshape(-1, 2) - uv).max() < 2e-4
