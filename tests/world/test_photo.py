"""Photographs: dots and markers land where the camera model says; the photo effects."""

import cv2
import numpy as np
import pytest

from vision_cal.errors import VisionCalError
from vision_cal.world.camera import default_views, look_at, project
from vision_cal.world.photo import SHADOW_STRENGTH
from vision_cal.world.sheet import DOT_RGB, sheet_texture

pytestmark = pytest.mark.render


def _views(sheet, K, size_px):
    """A view straight down and two tilted ones (20-30 deg)."""
    flat = default_views(sheet, n=1, size_px=size_px, K=K, tilt_deg=(0, 0), rng=1)
    tilted = default_views(sheet, n=2, size_px=size_px, K=K, tilt_deg=(20, 30), rng=2)
    return flat + tilted


def _dot_centres(img, bare, guesses_px, *, r=6):
    """Ink-coverage centroids near ``guesses_px``: coverage from the photo with and without dots."""
    img = img[..., 0].astype(float)
    bare = bare[..., 0].astype(float)
    alpha = (bare - img) / np.maximum(bare - DOT_RGB[0], 1.0)
    out = []
    for u, v in guesses_px:
        u0, v0 = int(round(u)), int(round(v))
        a = alpha[v0 - r:v0 + r + 1, u0 - r:u0 + r + 1]
        vv, uu = np.mgrid[v0 - r:v0 + r + 1, u0 - r:u0 + r + 1]
        out.append([np.sum(a * uu) / a.sum(), np.sum(a * vv) / a.sum()])
    return np.array(out)


@pytest.fixture(scope="module")
def plain_textures(small_sheet, small_marks):
    """Dots on uniform paper without grid: the render's geometry alone."""
    kw = dict(px_per_mm=8.0, grid=False, paper_grain=False, rng=7)
    return (sheet_texture(small_sheet, marks_xy_mm=small_marks, **kw),
            sheet_texture(small_sheet, marks_xy_mm=np.zeros((0, 2)), **kw))


@pytest.fixture(scope="module")
def full_textures(small_sheet, small_marks):
    kw = dict(px_per_mm=8.0, rng=8)
    return (sheet_texture(small_sheet, marks_xy_mm=small_marks, **kw),
            sheet_texture(small_sheet, marks_xy_mm=np.zeros((0, 2)), **kw))


def test_rendered_dots_land_on_the_projected_marks(photographer, K, small_sheet, small_marks,
                                                   plain_textures):
    tex, bare = plain_textures
    size = photographer.size_px
    for T in _views(small_sheet, K, size):
        img = photographer.render(tex, extent_mm=small_sheet.extent_mm, T_cam_sheet=T)
        img0 = photographer.render(bare, extent_mm=small_sheet.extent_mm, T_cam_sheet=T)
        assert img.shape == (size[1], size[0], 3) and img.dtype == np.uint8
        uv = project(small_marks, K=K, T_cam_sheet=T)
        err = _dot_centres(img, img0, uv) - uv
        # bench/render.py --accuracy prints the figures
        assert np.abs(err).max() < 0.05
        assert np.sqrt(np.mean(err ** 2)) < 0.02
        assert np.all(np.abs(err.mean(axis=0)) < 0.01)


def test_dots_on_the_real_paper(photographer, K, small_sheet, small_marks, full_textures):
    """With the plotting grid the per-pixel coverage estimate is blurred by grid lines."""
    tex, bare = full_textures
    T = _views(small_sheet, K, photographer.size_px)[1]
    img = photographer.render(tex, extent_mm=small_sheet.extent_mm, T_cam_sheet=T)
    img0 = photographer.render(bare, extent_mm=small_sheet.extent_mm, T_cam_sheet=T)
    uv = project(small_marks, K=K, T_cam_sheet=T)
    err = _dot_centres(img, img0, uv) - uv
    # bench/render.py --accuracy prints the figures
    assert np.abs(err).max() < 0.1
    assert np.sqrt(np.mean(err ** 2)) < 0.03


def test_render_keeps_the_texture_colours(photographer, K, small_sheet, full_textures):
    """Unlit flat render: seen straight down, a region's mean colour is the texture's."""
    _, bare = full_textures
    T = look_at(eye_mm=(0.0, 15.0, 480.0), target_mm=(0.0, 15.0))
    img = photographer.render(bare, extent_mm=small_sheet.extent_mm, T_cam_sheet=T)
    # pixels u0..u1-1, v0..v1-1 cover exactly this sheet rectangle (straight-down view)
    (u0, v1), (u1, v0) = np.round(project([[-60.0, -20.0], [60.0, 50.0]], K=K,
                                          T_cam_sheet=T)).astype(int)
    mm_per_px = 480.0 / photographer.K[0, 0]
    xa, xb = -(K[0, 2] - (u0 - 0.5)) * mm_per_px, ((u1 - 0.5) - K[0, 2]) * mm_per_px
    yb, ya = 15.0 + (K[1, 2] - (v0 - 0.5)) * mm_per_px, 15.0 - ((v1 - 0.5) - K[1, 2]) * mm_per_px
    got = img[v0:v1, u0:u1].reshape(-1, 3).mean(axis=0)
    x0, _, _, y1 = small_sheet.extent_mm
    ppm = 8.0
    ja, jb = int(round((xa - x0) * ppm)), int(round((xb - x0) * ppm))
    ia, ib = int(round((y1 - yb) * ppm)), int(round((y1 - ya) * ppm))
    ref = bare[ia:ib, ja:jb].reshape(-1, 3).mean(axis=0)
    assert (u1 - u0) * (v1 - v0) > 20000
    # seen: 0.8 grey levels brighter (llvmpipe rounds up in glGenerateMipmap and in the
    # bilinear filter: +0.25 without mipmaps), the same in all channels; a colour shift or
    # lighting would show as several levels and differ between channels
    assert np.all(got - ref > -0.3) and np.all(got - ref < 1.5)
    assert np.ptp(got - ref) < 0.3


def _detector():
    p = cv2.aruco.DetectorParameters()
    p.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    p.cornerRefinementWinSize = 3
    p.cornerRefinementMinAccuracy = 0.001
    p.cornerRefinementMaxIterations = 100
    return cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_5X5_100), p)


def test_markers_are_detected_where_the_camera_says(photographer, K, small_sheet,
                                                    full_textures):
    tex, _ = full_textures
    by_id = small_sheet.corners_by_id()
    errs = []
    for T in _views(small_sheet, K, photographer.size_px):
        img = photographer.render(tex, extent_mm=small_sheet.extent_mm, T_cam_sheet=T)
        corners, ids, _ = _detector().detectMarkers(cv2.cvtColor(img, cv2.COLOR_RGB2GRAY))
        assert ids is not None and sorted(np.ravel(ids).tolist()) == sorted(by_id)
        for c, i in zip(corners, np.ravel(ids)):
            errs.append(c.reshape(4, 2) - project(by_id[int(i)], K=K, T_cam_sheet=T))
    err = np.stack(errs)                              # (n, 4, 2)
    # mostly cornerSubPix pulling lone square corners inwards (it does the same on the
    # texture itself, test_sheet)
    assert np.sqrt(np.mean(err ** 2)) < 0.25
    assert np.abs(err).max() < 0.5
    # that pull is nearly symmetric: the mean of the four corners is where the camera says
    # (the rest is perspective and detector noise)
    centre_err = err.mean(axis=1)
    assert np.sqrt(np.mean(centre_err ** 2)) < 0.05
    assert np.abs(centre_err).max() < 0.12


def test_distorted_photo_matches_project_points(photographer, K, small_sheet, small_marks,
                                                plain_textures):
    tex, bare = plain_textures
    dist = np.array([-0.1, 0.0, 0.0, 0.0, 0.0])
    T = _views(small_sheet, K, photographer.size_px)[2]
    img = photographer.photograph(tex, extent_mm=small_sheet.extent_mm, T_cam_sheet=T,
                                  dist=dist)
    img0 = photographer.photograph(bare, extent_mm=small_sheet.extent_mm, T_cam_sheet=T,
                                   dist=dist)
    uv_d = project(small_marks, K=K, dist=dist, T_cam_sheet=T)
    uv_u = project(small_marks, K=K, T_cam_sheet=T)
    assert np.abs(uv_d - uv_u).max() > 1.5          # the lens moves dots by pixels
    err = _dot_centres(img, img0, uv_d) - uv_d
    # bench/render.py --accuracy prints the figures
    assert np.abs(err).max() < 0.06
    assert np.sqrt(np.mean(err ** 2)) < 0.025


def test_photo_effects(photographer, K, small_sheet, full_textures):
    tex, _ = full_textures
    T = look_at(eye_mm=(0.0, 5.0, 500.0), target_mm=(0.0, 5.0))
    ext = small_sheet.extent_mm
    clean = photographer.photograph(tex, extent_mm=ext, T_cam_sheet=T).astype(float)
    vig = photographer.photograph(tex, extent_mm=ext, T_cam_sheet=T, vignetting=0.4)
    ratio = vig.astype(float).sum(axis=2) / np.maximum(clean.sum(axis=2), 1)
    h, w = ratio.shape
    assert ratio[h // 2 - 5:h // 2 + 5, w // 2 - 5:w // 2 + 5].mean() == pytest.approx(1, abs=0.01)
    assert ratio[:6, :6].mean() == pytest.approx(0.6, abs=0.03)      # 40 % lost in corners
    noisy = photographer.photograph(tex, extent_mm=ext, T_cam_sheet=T, noise_sigma=3.0, rng=1)
    again = photographer.photograph(tex, extent_mm=ext, T_cam_sheet=T, noise_sigma=3.0, rng=1)
    np.testing.assert_array_equal(noisy, again)                        # seeded
    d = noisy.astype(float) - clean
    bright = clean > 200
    assert np.std(d[bright]) == pytest.approx(3.0 * np.sqrt(0.25 + 0.75 * 235 / 255), rel=0.1)
    jpg = photographer.photograph(tex, extent_mm=ext, T_cam_sheet=T, jpeg_quality=60)
    diff = np.abs(jpg.astype(float) - clean)
    assert 0.3 < diff.mean() < 8.0


def test_arm_hides_part_of_the_sheet_and_leaves_the_rest(photographer, K, small_sheet,
                                                        full_textures):
    tex, _ = full_textures
    T = look_at(eye_mm=(20.0, -40.0, 520.0), target_mm=(0.0, 15.0))
    ext = small_sheet.extent_mm
    # the key light comes from +x +y: shadows fall towards -x -y, the right part stays clear
    arm = [((-160.0, 120.0), (-40.0, 30.0), 30.0, 90.0), ((-40.0, 30.0), (30.0, -20.0), 20.0, 60.0)]
    no_arm = photographer.render(tex, extent_mm=ext, T_cam_sheet=T)
    with_arm = photographer.render(tex, extent_mm=ext, T_cam_sheet=T, arm=arm)
    # the arm covers the projection of a point on the middle of link 2 (60 mm up) ...
    p = np.array([[-5.0, 5.0, 55.0]])
    u, v = np.round(project(p, K=K, T_cam_sheet=T)[0]).astype(int)
    assert np.abs(with_arm[v, u].astype(float) - no_arm[v, u]).max() > 10
    # ... shaded: its pixels are not all one colour (several lights)
    diff = np.abs(with_arm.astype(float) - no_arm).max(axis=2)
    changed = diff > 0
    assert 0.03 < changed.mean() < 0.6
    # the shadow only darkens the paper, by at most SHADOW_STRENGTH
    ratio = with_arm.astype(float).sum(axis=2) / np.maximum(no_arm.astype(float).sum(axis=2), 1)
    far = np.zeros_like(changed)
    u_far = int(np.ceil(project([[55.0, 15.0]], K=K, T_cam_sheet=T)[0, 0]))
    far[:, u_far:] = True                           # sheet x > 55 mm and the table beyond
    np.testing.assert_array_equal(with_arm[far], no_arm[far])
    unlit = photographer.render(tex, extent_mm=ext, T_cam_sheet=T, arm=arm, lights=None)
    not_arm = np.all(unlit == no_arm, axis=2)       # no shadows without lights
    shadow = changed & not_arm
    assert shadow.sum() > 500
    assert np.all(ratio[shadow] <= 1.0) and np.all(ratio[shadow] > 1 - SHADOW_STRENGTH - 0.02)
    assert ratio[shadow].min() < 1 - 0.8 * SHADOW_STRENGTH   # a real umbra somewhere
    # a grey shadow: the same gain in every channel (up to rounding)
    gains = with_arm[shadow].astype(float) / no_arm[shadow]
    bright = no_arm[shadow].min(axis=1) > 150
    assert np.abs(gains[bright] - gains[bright].mean(axis=1, keepdims=True)).max() < 0.01
    # the arm's render is cached, and removed again
    again = photographer.render(tex, extent_mm=ext, T_cam_sheet=T)
    np.testing.assert_array_equal(again, no_arm)


def test_photographer_refuses_bad_input(photographer, small_sheet):
    T = look_at(eye_mm=(0.0, 0.0, 500.0), target_mm=(0.0, 0.0))
    with pytest.raises(VisionCalError, match="texture"):
        photographer.render(np.zeros((10, 10), np.uint8), extent_mm=small_sheet.extent_mm,
                            T_cam_sheet=T)
    with pytest.raises(VisionCalError, match=r"arm\[0\]"):
        photographer.render(np.zeros((10, 10, 3), np.uint8), extent_mm=small_sheet.extent_mm,
                            T_cam_sheet=T, arm=[(1.0, 2.0)])


def test_colour_only_read_back_is_pyrenders_own(photographer, small_sheet, full_textures):
    """A photo without the arm's shadows skips the depth read-back: its colour bytes are
    pyrender's own read-back (depth and colour) of the same render."""
    import pyrender

    tex, _ = full_textures
    T = look_at(eye_mm=(10.0, 5.0, 470.0), target_mm=(0.0, 15.0))
    fast = photographer.render(tex, extent_mm=small_sheet.extent_mm, T_cam_sheet=T)
    inner = photographer._renderer._renderer
    assert "_read_main_framebuffer" not in vars(inner)      # the patch is never left behind
    full, depth = photographer._renderer.render(photographer._scene,
                                                flags=pyrender.RenderFlags.FLAT)
    assert depth is not None and depth.shape == full.shape[:2]
    w, h = photographer.size_px
    np.testing.assert_array_equal(fast, cv2.resize(full, (w, h), interpolation=cv2.INTER_AREA))


def test_shadow_window_is_the_whole_resize_where_a_shadow_shows():
    """The shadow mask resized in its window only: the same values as the whole image's
    resize there, and below the visible level everywhere else."""
    from vision_cal.world.photo import SHADOW_VISIBLE, _shadow_window

    q, hs, ws = 4, 96, 160
    for blob, sigma in (((10, 17), 1.5), ((0, 0), 2.0), ((23, 39), 0.8)):
        small = np.zeros((hs // q, ws // q), np.float32)
        small[blob] = 1.0
        small = cv2.GaussianBlur(small, (0, 0), sigma)
        whole = cv2.resize(small, (ws, hs), interpolation=cv2.INTER_LINEAR)
        (r0, r1, c0, c1), part = _shadow_window(small, hs, ws, q)
        assert r1 - r0 < hs or c1 - c0 < ws                  # a window, not the image
        np.testing.assert_array_equal(part, whole[r0:r1, c0:c1])
        outside = whole.copy()
        outside[r0:r1, c0:c1] = 0.0
        assert outside.max() < SHADOW_VISIBLE
    assert _shadow_window(np.zeros((24, 40), np.float32), hs, ws, q) is None
    # a shadow below the visible level leaves every grey level as it was
    c = np.arange(256, dtype=np.float32)
    gain = 1.0 - SHADOW_STRENGTH * np.float32(SHADOW_VISIBLE)
    np.testing.assert_array_equal(np.rint(c * gain), c)
    odd = np.ones((25, 40), np.float32)                       # q does not divide 97 rows
    (r0, r1, c0, c1), part = _shadow_window(odd, 97, ws, q)
    assert (r0, r1, c0, c1) == (0, 97, 0, ws) and part.shape == (97, ws)


def test_depth_window_is_pyrenders_depth(photographer, small_sheet, full_textures):
    """The shadows' depth, read back in a window, is pyrender's whole depth image there."""
    import pyrender

    from vision_cal.world.photo import _read_depth_window

    tex, _ = full_textures
    T = look_at(eye_mm=(20.0, -40.0, 520.0), target_mm=(0.0, 15.0))
    arm = [((-160.0, 120.0), (-40.0, 30.0), 30.0, 90.0)]
    photographer.render(tex, extent_mm=small_sheet.extent_mm, T_cam_sheet=T, arm=arm)
    _, depth = photographer._renderer.render(photographer._scene,
                                             flags=pyrender.RenderFlags.FLAT)
    cam = photographer._camera
    hs, ws = depth.shape
    for r0, r1, c0, c1 in ((0, hs, 0, ws), (37, 411, 120, 777), (hs - 50, hs, 0, 64)):
        part = _read_depth_window(photographer._renderer._renderer, r0, r1, c0, c1,
                                  cam.znear, cam.zfar)
        np.testing.assert_array_equal(part, depth[r0:r1, c0:c1])
    assert np.ptp(depth) > 100.0                               # arm, paper and table


def test_a_patched_texture_renders_as_a_fresh_upload(photographer, small_sheet,
                                                     full_textures):
    """A series photo changes a few texels: only they are uploaded and the mipmaps rebuilt,
    and the photo is the same, byte for byte, as one from a texture uploaded whole
    (tilted: the coarser mipmap levels are sampled too)."""
    full, bare = full_textures
    T = default_views(small_sheet, n=1, size_px=photographer.size_px, K=photographer.K,
                      tilt_deg=(35, 35), rng=3)[0]
    ext = small_sheet.extent_mm
    patched = bare.copy()
    patched[200:260, 300:420] = full[200:260, 300:420]
    assert np.any(patched != bare)
    photographer.render(bare, extent_mm=ext, T_cam_sheet=T)
    uploaded = photographer._sheet_texture
    fast = photographer.render(patched, extent_mm=ext, T_cam_sheet=T)
    assert photographer._sheet_texture is uploaded               # patched, not re-uploaded
    photographer.render(bare[:-8], extent_mm=ext, T_cam_sheet=T)  # another shape: a new one
    fresh = photographer.render(patched, extent_mm=ext, T_cam_sheet=T)
    assert photographer._sheet_texture is not uploaded
    np.testing.assert_array_equal(fast, fresh)
    assert np.any(fast != photographer.render(bare, extent_mm=ext, T_cam_sheet=T))
