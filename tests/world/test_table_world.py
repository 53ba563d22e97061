"""The world of a sheet on a table, an object on it, two cameras (worlds/table_world.py,
issue 37): its ray caster puts every printed corner where OpenCV's own projection of the
raised, printed point puts it, and the block hides what is behind it. Small images."""

from dataclasses import replace

import cv2
import numpy as np
import pytest

from vision_cal.world.camera import camera_matrix, look_at, phone_lens
from worlds.table_world import Box, TableCamera, _rays, table_world

SIZE = (480, 360)


@pytest.fixture(scope="module")
def world():
    """3 x 2 markers of 40 mm, waves of 3 mm (so that the heights show), no block."""
    return table_world(5, grid=(3, 2), marker_mm=40.0, pitch_mm=70.0, waves_mm=3.0,
                       box=False, ppm=4.0, dictionary="DICT_5X5_100")


def _camera():
    f = 525.0
    K = camera_matrix(size_px=SIZE, f_px=f, principal_px=(241.5, 177.0))
    dist = np.array(phone_lens(f_px=f, size_px=SIZE, k1=0.08, k2=-0.1, tangential_px=3.0,
                               prism_px=3.0, rng=2))
    return TableCamera("test", SIZE, K, dist, noise=0.5, blur_px=0.4)


def _detect(img, dictionary):
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary)))
    corners, ids, _ = det.detectMarkers(cv2.cvtColor(img, cv2.COLOR_RGB2GRAY))
    if ids is None:
        return {}
    gray = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    out = {}
    for i, c in zip(np.asarray(ids).ravel(), corners):
        c = cv2.cornerSubPix(gray, np.asarray(c, np.float32).reshape(-1, 1, 2), (4, 4), (-1, -1),
                             (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 1e-3))
        out[int(i)] = c.reshape(4, 2)
    return out


def test_the_ray_caster_inverts_opencvs_projection_of_the_raised_print(world):
    """The pixel where ``cv2.projectPoints`` puts each printed corner at its height on the
    waves (through a lens with tangential and thin-prism terms, 25 deg off vertical) casts
    back onto that corner within 1e-4 mm; the same corners taken flat on the table project
    pixels away (the heights are what the photos see)."""
    cam = _camera()
    T = look_at(eye_mm=(-150.0, -200.0, 560.0), target_mm=(0.0, 0.0), up_hint=(0.1, 1.0, 0.0))
    P = world.corners_3d().reshape(-1, 3)
    rvec = cv2.Rodrigues(T[:3, :3])[0]
    uv = cv2.projectPoints(P, rvec, T[:3, 3], cam.K, cam.dist)[0].reshape(-1, 2)
    xy, _, on = world._meet_paper(*_rays(cam, T, uv))    # the photograph's own rays
    assert np.abs(xy - P[:, :2]).max() < 1e-4 and on.all() and not world.hidden(T).any()
    flat = np.column_stack([P[:, :2], np.zeros(len(P))])
    off = cv2.projectPoints(flat, rvec, T[:3, 3], cam.K, cam.dist)[0].reshape(-1, 2)
    assert np.linalg.norm(off - uv, axis=1).max() > 1.0
    # and the render shows them there: each marker's centre (the mean of its corners found
    # by OpenCV: cornerSubPix's pull along each corner's diagonal nearly cancels) within
    # 0.15 px of the projection's (a half-pixel slip of the sampling would be 0.5)
    found = _detect(world.photograph(cam, T, rng=1, supersample=2), world.sheet.aruco_dictionary)
    got = np.array([found[m.id] for m in world.sheet.markers])
    assert np.linalg.norm((got - uv.reshape(-1, 4, 2)).mean(axis=1), axis=1).max() < 0.15


def test_the_block_hides_the_markers_behind_it(world):
    """A block in the middle of the paper, seen from one side: the markers it hides are not
    found, the others are."""
    w = replace(world, box=Box((0.0, -20.0), (60.0, 50.0, 80.0), 20.0))
    cam = _camera()
    T = look_at(eye_mm=(0.0, -380.0, 420.0), target_mm=(0.0, 0.0))
    hidden = w.hidden(T)
    assert 0 < hidden.sum() < len(hidden)
    found = _detect(w.photograph(cam, T, rng=2, supersample=1), w.sheet.aruco_dictionary)
    ids = np.array([m.id for m in w.sheet.markers])
    assert not set(ids[hidden].tolist()) & set(found)
    assert set(ids[~hidden].tolist()) <= set(found)
