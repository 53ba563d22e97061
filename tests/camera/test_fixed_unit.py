"""Still camera without rendering: grouping by pose, the focal-length degeneracy of a camera
looking straight down, and the cameras entry read back field by field."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from vision_cal.camera.fixed import (camera_from_json, camera_of, fit_pose, still_groups)
from vision_cal.errors import VisionCalError
from vision_cal.measure.mapping import fit_mapping

SIZE = (1200, 900)
K = np.array([[1300.0, 0, 599.5], [0, 1300.0, 449.5], [0, 0, 1]])
GRID_MM = np.array([[x, y] for x in np.linspace(-250, 250, 9) for y in np.linspace(-180, 180, 7)])


def _camera(tilt_deg: float):
    """T_cam_sheet of a camera 700 mm above the sheet's centre, turned about x by tilt."""
    a = np.radians(180.0 + tilt_deg)
    R = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    eye = np.array([0.0, -700.0 * np.sin(np.radians(tilt_deg)), 700.0 * np.cos(np.radians(tilt_deg))])
    return R, -R @ eye


def _project(R, t, xy):
    p = np.column_stack([xy, np.zeros(len(xy))]) @ R.T + t
    return p[:, :2] / p[:, 2:3] * K[0, 0] + K[:2, 2]


def _photo(uv, xy, file):
    return SimpleNamespace(status="ok", mapping=fit_mapping(xy, uv), size_px=SIZE, file=file)


def test_photos_from_one_place_are_grouped_and_a_moved_one_is_not():
    R, t = _camera(8.0)
    uv = _project(R, t, GRID_MM)
    rng = np.random.default_rng(3)
    same = [_photo(uv + rng.normal(0, 0.03, uv.shape), GRID_MM, f"s{i}") for i in range(3)]
    moved = _photo(uv + [0.8, 0.0], GRID_MM, "moved")     # the camera nudged by 0.8 px
    skipped = SimpleNamespace(status="skipped", mapping=None, size_px=SIZE, file="bad")
    groups = still_groups([same[0], skipped, same[1], moved, same[2]], GRID_MM)
    assert groups == [[0, 2, 4], [3]]


def test_looking_straight_down_leaves_the_focal_length_free_and_tilt_fixes_it():
    """A plane seen square-on is a similarity: f and the distance trade exactly, so the fit's
    f std must blow up; a 25 deg tilt brings perspective that pins f (truth within 4 std)."""
    rng = np.random.default_rng(11)
    f_std = {}
    for tilt in (0.0, 25.0):
        R, t = _camera(tilt)
        uv = _project(R, t, GRID_MM) + rng.normal(0, 0.05, (len(GRID_MM), 2))
        K0 = K.copy()
        K0[0, 0] = K0[1, 1] = 1200.0
        _, K_fit, cov, rms = fit_pose(GRID_MM, uv, K0, np.zeros(5), free_f=True)
        f_std[tilt] = np.sqrt(cov[6, 6])
        assert rms < 0.1
        if tilt:
            assert abs(K_fit[0, 0] - K[0, 0]) < 4 * f_std[tilt]
    assert f_std[0.0] > 20 * f_std[25.0], f_std


def test_pose_with_declared_lens_has_no_focal_std():
    R, t = _camera(10.0)
    uv = _project(R, t, GRID_MM)
    T, K_fit, cov, rms = fit_pose(GRID_MM, uv, K, np.zeros(5), free_f=False)
    assert np.allclose(T[:3, :3], R, atol=1e-9) and np.allclose(T[:3, 3], t, atol=1e-6)
    assert cov[6, 6] == 0 and np.array_equal(K_fit, K)


def _entry():
    down = np.diag([1.0, -1.0, -1.0, 1.0])          # looking down at the sheet from 800 mm
    down[2, 3] = 800.0
    return {"images": ["a.png"], "size_px": [1200, 900], "K": K.tolist(), "dist": [0] * 5,
            "T_robot_camera": down.tolist(),
            "robot_to_sheet": {"z1_deg": 1.0, "base_mm": [1.0, 2.0],
                               "sheet_matrix": np.eye(2).tolist()}}


@pytest.mark.parametrize("key,value,field", [
    ("K", [[1, 0], [0, 1]], "cameras[0].K"),
    ("T_robot_camera", None, "cameras[0].T_robot_camera"),
    ("dist", ["x"], "cameras[0].dist"),
    ("robot_to_sheet", {"z1_deg": 1.0}, "cameras[0].robot_to_sheet"),
])
def test_bad_cameras_entry_names_its_field(key, value, field):
    e = _entry()
    if value is None:
        del e[key]
    else:
        e[key] = value
    with pytest.raises(VisionCalError) as ei:
        camera_of({"cameras": [e]}, 0, file="cal.json")
    assert f"cal.json: {field}" in str(ei.value)


def test_no_still_camera_is_said():
    with pytest.raises(VisionCalError, match="cameras"):
        camera_of({}, 0, file="cal.json")
    cam = camera_from_json(_entry())
    assert np.all(cam.std == 0)          # no covariance written: no std claimed


def test_square_on_camera_maps_the_plane_and_refuses_other_heights():
    from vision_cal.camera.fixed import UNDETERMINED, fixed_camera, locate

    R, t = _camera(0.0)
    rng = np.random.default_rng(5)
    corners = {i: GRID_MM[4 * i:4 * i + 4] for i in range(len(GRID_MM) // 4)}
    ids = np.array(sorted(corners))
    photos = []
    for k in range(2):
        px = np.stack([_project(R, t, corners[i]) for i in ids]) + rng.normal(0, 0.05, (len(ids), 4, 2))
        photos.append(SimpleNamespace(file=f"p{k}", marker_ids=ids, markers_px=px, size_px=SIZE))
    K0 = K.copy()
    K0[0, 0] = K0[1, 1] = 1100.0          # a wrong guess: the fit cannot correct it
    cam = fixed_camera(photos, [0, 1], corners, K=K0, dist=np.zeros(5), free_f=True,
                       robot3=np.zeros(3), cov3=np.zeros((3, 3)), sheet_matrix=np.eye(2),
                       intrinsics="estimated")
    assert cam.intrinsics == UNDETERMINED and "note" in cam.to_json()
    xy = np.array([[100.0, 50.0], [-200.0, 120.0]])
    (a, b) = locate(cam, _project(R, t, xy), 0.0)
    assert np.allclose([a.sheet_mm[:2], b.sheet_mm[:2]], xy, atol=0.05)
    with pytest.raises(VisionCalError, match="--z-mm"):
        locate(cam, _project(R, t, xy), 50.0)
