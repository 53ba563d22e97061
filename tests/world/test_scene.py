"""Scene files: every shipped scene loads; bad fields fail in one line naming file and field."""

from pathlib import Path

import numpy as np
import pytest

from vision_cal.errors import VisionCalError
from vision_cal.model.kinematics import forward
from vision_cal.model.robot import JointBacklash, SheetAffine
from vision_cal.world.scene import Scene, load_scene, scene_from_dict

RENDERS = Path(__file__).resolve().parents[2] / "renders"
SCENES = sorted(RENDERS.glob("*.yaml"))
EXPECTED = {"default", "clean", "backlash_j1", "scale_j2", "cyclic_j1_h1", "cyclic_j2_h2",
            "lens_barrel", "lens_pincushion", "sheet_shrink_x", "single_photo", "paper", "small"}


def test_every_expected_scene_is_shipped():
    assert EXPECTED <= {p.stem for p in SCENES}


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
def test_shipped_scene_loads(path):
    s = load_scene(path)
    assert s.source == str(path)
    assert s.photos.mode in ("series", "single", "survey")


def test_default_scene_matches_the_issue():
    s = load_scene(RENDERS / "default.yaml")
    t = s.robot.truth
    assert (t.L1_mm, t.L2_mm, t.z1_deg, t.z2_deg) == (344.05, 259.87, -2.57, -8.13)
    n = s.robot.nominal
    assert (n.L1_mm, n.L2_mm, n.joint_zero_deg) == (350.0, 260.0, (0.0, 0.0))
    off = np.hypot(*(np.subtract(n.base_mm, t.base_mm)))
    assert 10 <= off <= 80, "nominal base is a rough guess tens of mm off"
    assert s.robot.effects == (JointBacklash(joint=2, deg=0.1),)
    assert s.robot.repeatability_mm == 0.01
    assert (s.plan.kind, s.plan.n_calibration, s.plan.n_validation) == ("informative", 30, 8)
    assert s.camera.size_px == (2400, 1800) and s.photos.mode == "series"
    # base outside the paper, sheet origin comfortably reachable
    x0, y0, x1, y1 = (s.sheet.bottom_left_mm[0], s.sheet.bottom_left_mm[1],
                      s.sheet.bottom_left_mm[0] + s.sheet.size_mm[0],
                      s.sheet.bottom_left_mm[1] + s.sheet.size_mm[1])
    bx, by = t.base_mm
    assert not (x0 <= bx <= x1 and y0 <= by <= y1)
    r = np.hypot(bx, by)
    assert abs(t.L1_mm - t.L2_mm) + 100 < r < t.L1_mm + t.L2_mm - 100


def test_sheet_shrink_is_an_uneven_affine():
    s = load_scene(RENDERS / "sheet_shrink_x.yaml")
    (e,) = s.robot.effects
    assert isinstance(e, SheetAffine)
    assert np.allclose(e.M, [[1.002, 0], [0, 1]])   # shrunk: printed distances read longer


def test_lens_scenes_hide_the_lens():
    for name, sign in (("lens_barrel", -1), ("lens_pincushion", 1)):
        s = load_scene(RENDERS / f"{name}.yaml")
        assert not s.camera.declared
        assert np.sign(s.camera.dist[0]) == sign


def test_paper_scene_marks_fall_on_the_sheet():
    from vision_cal.plan.calibration_plan import paper_plan

    s = load_scene(RENDERS / "paper.yaml")
    q = np.array([m.joints_deg for m in paper_plan()])
    xy = forward(s.robot.truth, q)
    x0, y0 = s.sheet.bottom_left_mm
    w, h = s.sheet.size_mm
    assert np.all((xy[:, 0] > x0 + 20) & (xy[:, 0] < x0 + w - 20))
    assert np.all((xy[:, 1] > y0 + 20) & (xy[:, 1] < y0 + h - 20))


def test_empty_scene_is_the_default_world():
    s = scene_from_dict(None)
    assert s == Scene(source="<scene>")
    assert s.robot.effects == ()


def test_the_survey_block_photographs_the_same_world_blank():
    """``survey``: the default is no survey; the block's photos are the same world (seed,
    robot, sheet and its print, lens) with the blank sheet seen from its places."""
    assert scene_from_dict({}).survey is None
    s = scene_from_dict({"seed": 5, "sheet": {"print": {"deviation_rms_mm": 0.1}},
                         "camera": {"moving": False}, "photos": {"arm_parked": True},
                         "survey": {"n_views": 7, "tilt_deg": 25}})
    assert (s.survey.n_views, s.survey.tilt_deg) == (7, (0.0, 25.0))
    assert s.photos.mode == "series" and s.camera.n_views == 4   # the session's own
    sv = s.survey_photos()
    assert (sv.seed, sv.robot, sv.sheet) == (s.seed, s.robot, s.sheet)
    assert (sv.camera.size_px, sv.camera.f_px, sv.camera.dist) == (
        s.camera.size_px, s.camera.f_px, s.camera.dist)
    assert (sv.camera.n_views, sv.camera.tilt_deg) == (7, (0.0, 25.0))
    assert sv.photos.mode == "survey" and not sv.photos.arm_parked
    assert scene_from_dict({"survey": {}}).survey.n_views == 6
    with pytest.raises(VisionCalError, match="survey: the scene has no survey block"):
        scene_from_dict({}).survey_photos()


def test_overrides():
    s = scene_from_dict({"seed": 3}).with_overrides(seed=9, mode="single")
    assert s.seed == 9 and s.photos.mode == "single"
    with pytest.raises(VisionCalError, match="--mode"):
        s.with_overrides(mode="movie")


@pytest.mark.parametrize("tree, field", [
    ({"seed": -1}, "seed"),
    ({"seed": 1.5}, "seed"),
    ({"robot": {"truth": {"L1_mm": -3}}}, "robot.truth.L1_mm"),
    ({"robot": {"truth": {"base_mm": [1, 2, 3]}}}, "robot.truth.base_mm"),
    ({"robot": {"nominal": {"home_deg": [0, "x"]}}}, "robot.nominal.home_deg[1]"),
    ({"robot": {"nominal": {"lenght": 3}}}, "robot.nominal.lenght"),
    ({"robot": {"effects": [{"name": "joint_backlash", "joint": 3, "deg": 0.1}]}},
     "robot.effects[0]"),
    ({"robot": {"effects": [{"name": "warp"}]}}, "robot.effects[0]"),
    ({"robot": {"effects": "backlash"}}, "robot.effects"),
    ({"robot": {"repeatability_mm": -0.1}}, "robot.repeatability_mm"),
    ({"sheet": {"dictionary": "DICT_9X9_1"}}, "sheet.dictionary"),
    ({"sheet": {"grid": [0, 3]}}, "sheet.grid[0]"),
    ({"sheet": {"marker_mm": 500}}, "sheet.marker_mm"),
    ({"sheet": {"grid": [30, 20]}}, "sheet.grid"),
    ({"sheet": {"grid": "7x5"}}, "sheet.grid"),
    ({"plan": {"kind": "random"}}, "plan.kind"),
    ({"plan": {"n_calibration": 0}}, "plan.n_calibration"),
    ({"camera": {"size_px": [800]}}, "camera.size_px"),
    ({"camera": {"dist": [0, 0, 0]}}, "camera.dist"),
    ({"camera": {"declared": "yes"}}, "camera.declared"),
    ({"camera": {"tilt_deg": [30, 10]}}, "camera.tilt_deg"),
    ({"camera": {"fill": 1.5}}, "camera.fill"),
    ({"photos": {"mode": "movie"}}, "photos.mode"),
    ({"photos": {"jpeg_quality": 101}}, "photos.jpeg_quality"),
    ({"photos": {"texture_px_per_mm": 0.7}}, "photos.texture_px_per_mm"),
    ({"photos": {"extra_files": [{"file": "../x.png"}]}}, "photos.extra_files[0].file"),
    ({"photos": {"extra_files": [{"file": "b.png", "kind": "torn"}]}},
     "photos.extra_files[0].kind"),
    ({"survey": {"n_views": 2}}, "survey.n_views"),
    ({"survey": {"n_views": 51}}, "survey.n_views"),
    ({"survey": {"tilt_deg": [30, 10]}}, "survey.tilt_deg"),
    ({"survey": {"tilt_deg": [10, 61]}}, "survey.tilt_deg[1]"),
    ({"survey": {"views": 6}}, "survey.views"),
    ({"survey": 6}, "survey"),
    ({"lights": {}}, "lights"),
    ([1, 2], None),
])
def test_bad_field_is_named(tree, field):
    with pytest.raises(VisionCalError) as e:
        scene_from_dict(tree, file="s.yaml")
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith("s.yaml: ")
    if field is not None:
        assert e.value.field == field
        assert f"s.yaml: {field}: " in msg


def test_yaml_errors_name_the_file(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text("seed: [1,\nrobot: {")
    with pytest.raises(VisionCalError, match=r"bad\.yaml: not valid YAML \(line"):
        load_scene(p)
    with pytest.raises(VisionCalError, match="not found"):
        load_scene(tmp_path / "missing.yaml")
