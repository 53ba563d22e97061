"""Marks against the printed grid around them: the local reference undoes what the marker
mapping gets wrong (a raised paper's parallax), and claims nothing on a flat sheet."""

import numpy as np
import pytest

from tests.measure import synth_measure as sm
from vision_cal.dataset.session import SheetGrid
from vision_cal.measure.grid import grid_offset
from vision_cal.measure.height import HeightMap, camera_centre_mm, height_from_grid
from vision_cal.measure.mapping import fit_mapping
from vision_cal.world.camera import project


@pytest.fixture(scope="module")
def scene():
    sheet = sm.small_sheet()
    marks = sm.free_targets(sheet, 12, rng=5)
    tex = sm.texture(sheet, marks, rng=3)
    K, T = sm.view(tilt_deg=15.0)
    img = sm.photo(sheet, tex, K=K, T=T, noise=2.0, rng=4)
    return sheet, marks, img, K, T


def _mapping_shifted(K, T, shift_mm):
    """The homography of the view, wrong by a translation of ``shift_mm`` on the sheet:
    what a mapping through raised markers (or a bad fit) does locally."""
    g = np.array([[x, y] for x in np.arange(-100.0, 101.0, 25.0)
                  for y in np.arange(-80.0, 81.0, 20.0)])
    uv = project(g, K=K, T_cam_sheet=T)
    return fit_mapping(g + shift_mm, uv)


@pytest.mark.parametrize("shift", [(0.0, 0.0), (0.21, -0.13), (-0.35, 0.3)])
def test_grid_offset_recovers_a_wrong_mapping(scene, shift):
    """The grid lines seen around each dot are off by exactly the mapping's error; the
    dot measured against them is where the texture put it (bound: 4 reported std plus
    the per-photo floor of the line phase)."""
    sheet, marks, img, K, T = scene
    m = _mapping_shifted(K, T, np.array(shift))
    grid = sheet.grid_spec
    assert isinstance(grid, SheetGrid) and grid.pitch_mm == 1.0
    uv = project(marks, K=K, T_cam_sheet=T)
    for p_mm, (u, v) in zip(marks, uv):
        hp = 60
        u0, v0 = int(round(u)) - hp, int(round(v)) - hp
        patch = img[v0:v0 + 2 * hp + 1, u0:u0 + 2 * hp + 1]
        seen = m.image_to_sheet([[u, v]])[0]          # mapped position, wrong by shift
        go = grid_offset(patch, (u0, v0), m, seen, grid, exclude_r_mm=1.2)
        assert go is not None
        sd = np.sqrt(np.diag(go.cov_mm2))
        assert np.all(np.abs(go.d_mm - np.array(shift)) < 4 * sd + 0.01), (go.d_mm, sd)


def test_grid_offset_refuses_bare_paper(scene):
    sheet, marks, img, K, T = scene
    m = _mapping_shifted(K, T, np.zeros(2))
    far = SheetGrid(1.0, 10, (0.0, 0.0), extent_mm=(500.0, 500.0, 600.0, 600.0))
    u, v = project(marks[:1], K=K, T_cam_sheet=T)[0]
    u0, v0 = int(round(u)) - 60, int(round(v)) - 60
    patch = img[v0:v0 + 121, u0:u0 + 121]
    assert grid_offset(patch, (u0, v0), m, marks[0], far, exclude_r_mm=1.2) is None


def test_height_from_the_grid_offset():
    """d = z (p - C_xy) / C_z: the height comes back, and the camera centre from H and K."""
    from vision_cal.world.camera import camera_matrix, look_at

    K = camera_matrix(size_px=(800, 600), f_px=900.0)
    C = np.array([60.0, -150.0, 700.0])
    T = look_at(eye_mm=C, target_mm=(0.0, 0.0))
    H = K @ np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]])
    assert np.allclose(camera_centre_mm(H * 3.7, K), C, atol=1e-6)
    p, z = np.array([120.0, 80.0]), 0.4
    d = z * (p - C[:2]) / C[2]
    h = height_from_grid([(C, p, d, np.eye(2) * 1e-6)])
    assert h.z_mm == pytest.approx(z, rel=1e-9)


def test_height_map_claims_only_what_is_there():
    rng = np.random.default_rng(2)
    xy = rng.uniform([-250, -180], [250, 180], (40, 2))
    # noise larger than the claim threshold: only the chi-square against the std can tell
    flat = HeightMap.from_estimate(xy, rng.normal(0, 0.04, 40), np.full(40, 0.04),
                                   (-297, -210, 297, 210))
    assert flat.max_abs_mark_mm > 0.05 and not flat.claimed
    sd = np.full(40, 0.02)
    bump = 0.5 * np.exp(-np.sum((xy - [50, 20]) ** 2, axis=1) / (2 * 60.0**2))
    hm = HeightMap.from_estimate(xy, bump + rng.normal(0, 0.02, 40), sd, (-297, -210, 297, 210))
    assert hm.claimed
    # the map between marks follows the bump within 4 of its own std (+ the marks' noise)
    probe = np.array([[50.0, 20.0], [0.0, 0.0], [-100.0, 100.0]])
    true = 0.5 * np.exp(-np.sum((probe - [50, 20]) ** 2, axis=1) / (2 * 60.0**2))
    from scipy.interpolate import RegularGridInterpolator

    fs = RegularGridInterpolator((hm.y_mm, hm.x_mm), hm.std_mm)
    assert np.all(np.abs(hm.at(probe) - true) < 4 * fs(probe[:, ::-1]) + 0.03)
