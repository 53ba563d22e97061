"""A sheet that is not flat: the raised ink moves in the photo as the camera's geometry says."""

import numpy as np
import pytest

from vision_cal.world.camera import look_at, project
from vision_cal.world.height import Bump, Curl, HeightField, HeightScene, RandomBumps
from vision_cal.world.sheet import sheet_texture

pytestmark = pytest.mark.render

from tests.world.test_photo import _dot_centres  # noqa: E402


def test_height_field_parts():
    ext = (-100.0, -60.0, 100.0, 90.0)
    f = HeightField(ext, (Bump((10.0, 5.0), 20.0, 0.65),), (Curl("right", 1.5, 40.0),), 0.3)
    # bump top, curl at the edge, sag zero at the edges and -0.3 in the middle
    assert f.height_mm([[10.0, 5.0]])[0] == pytest.approx(
        0.65 + HeightField(ext, (), (), 0.3).height_mm([[10.0, 5.0]])[0], abs=1e-9)
    assert HeightField(ext, (), (Curl("right", 1.5, 40.0),)).height_mm([[100.0, 0.0]])[0] \
        == pytest.approx(1.5)
    assert HeightField(ext, (), (Curl("right", 1.5, 40.0),)).height_mm([[60.0, 0.0]])[0] == 0.0
    assert HeightField(ext, sag_mm=0.3).height_mm([[0.0, 15.0]])[0] == pytest.approx(-0.3)
    assert HeightField(ext, sag_mm=0.3).height_mm([[-100.0, 15.0]])[0] == pytest.approx(0.0)
    xs, ys, Z = f.grid(2.0)
    assert xs[0] == ext[0] and xs[-1] == ext[2] and ys[-1] == ext[3] and Z.shape == (76, 101)
    # random bumps: reproducible from the seed, different for another seed
    hs = HeightScene(random=RandomBumps(4))
    assert hs.field(ext, 3) == hs.field(ext, 3)
    assert hs.field(ext, 3) != hs.field(ext, 4)


def test_raised_ink_moves_by_z_r_over_H(photographer, K, small_sheet, small_marks):
    """Anchor: a dot raised by z, seen from a camera H above the paper, moves in the image
    by the projection of (x, y, z) minus that of (x, y, 0); on the paper that is
    z * (p - C) / (H - z), i.e. z * r / H outwards from the nadir, computed by hand here."""
    kw = dict(px_per_mm=8.0, grid=False, paper_grain=False, rng=7)
    tex = sheet_texture(small_sheet, marks_xy_mm=small_marks, **kw)
    bare = sheet_texture(small_sheet, marks_xy_mm=np.zeros((0, 2)), **kw)
    ext = small_sheet.extent_mm
    # a broad 2 mm bump: big enough to see the shift in pixels at this small size
    field = HeightField(ext, (Bump((0.0, 15.0), 45.0, 2.0),))
    grid = field.grid()
    C = np.array([40.0, -120.0, 260.0])                       # tilted ~25 deg
    T = look_at(eye_mm=C, target_mm=(0.0, 15.0))
    img_flat = photographer.render(tex, extent_mm=ext, T_cam_sheet=T)
    img0_flat = photographer.render(bare, extent_mm=ext, T_cam_sheet=T)
    img = photographer.render(tex, extent_mm=ext, T_cam_sheet=T, height_grid=grid)
    img0 = photographer.render(bare, extent_mm=ext, T_cam_sheet=T, height_grid=grid)
    uv0 = project(small_marks, K=K, T_cam_sheet=T)
    z = field.height_mm(small_marks)
    # hand computation: where the ray through the raised point meets z = 0
    H = C[2]
    p_apparent = small_marks + z[:, None] * (small_marks - C[:2]) / (H - z[:, None])
    uv_hand = project(p_apparent, K=K, T_cam_sheet=T)
    seen = _dot_centres(img, img0, uv_hand)
    seen_flat = _dot_centres(img_flat, img0_flat, uv0)
    shift_px = np.hypot(*(uv_hand - uv0).T)
    assert shift_px.max() > 1.0                     # the effect is really there
    # the raised render moves each dot as the hand computation says (flat render as the
    # reference cancels the render's own sub-0.03 px errors)
    err = (seen - seen_flat) - (uv_hand - uv0)
    assert np.abs(err).max() < 0.08
    assert np.sqrt(np.mean(err**2)) < 0.03
    # and it is the z * r / H of the issue to first order
    r = np.hypot(*(small_marks - C[:2]).T)
    assert np.allclose(np.hypot(*(p_apparent - small_marks).T), z * r / H, rtol=0.02, atol=1e-4)


def test_rendered_dataset_records_the_field(tmp_path):
    from vision_cal.estimate.paper import pilot_params
    from vision_cal.dataset.io import read_json
    from vision_cal.world.dataset import render_dataset
    from vision_cal.world.scene import scene_from_dict

    sc = scene_from_dict({"seed": 3, "robot": {"controller": "kinematic", "nominal": {
        "L1_mm": 344.0, "L2_mm": 260.0, "joint_zero_deg": [-2.5, -8.0],
        "base_mm": [-415.0, -234.0]}, "pen_diameter_mm": 2.0},
        "sheet": {"height": {"bumps": [{"centre_mm": [0, 0], "sigma_mm": 50,
                                        "height_mm": 0.6}], "sag_mm": 0.2}},
        "plan": {"n_calibration": 4, "n_validation": 0},
        "camera": {"size_px": [400, 300], "f_px": 430.0}, "photos": {
            "mode": "single", "texture_px_per_mm": 1.0}})
    out = render_dataset(sc, tmp_path / "d", pilot=pilot_params)
    t = read_json(out / "truth.json")
    assert t["sheet_height"]["bumps"][0]["height_mm"] == 0.6
    assert "sheet_height" in [e["name"] for e in t["effects"]]
    g = t["sheet_height"]["grid"]
    assert np.asarray(g["z_mm"]).shape == (len(g["y_mm"]), len(g["x_mm"]))
    f = sc.sheet.height.field(sc.sheet_extent if hasattr(sc, "sheet_extent") else
                              (-297.0, -210.0, 297.0, 210.0), 3)
    for k, z in t["mark_height_mm"].items():
        assert z == pytest.approx(f.height_mm([t["marks"][k]])[0])
