"""Rendering a scene into a dataset folder in the shared format."""

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from vision_cal.dataset.session import load_session
from vision_cal.errors import VisionCalError
from vision_cal.estimate.paper import pilot_params
from vision_cal.model.robot import RobotModel
from vision_cal.world import dataset as ds
from vision_cal.world.camera import project
from vision_cal.world.scene import load_scene
from vision_cal.world.sheet import make_sheet, sheet_texture

RENDERS = Path(__file__).resolve().parents[2] / "renders"
SMALL = load_scene(RENDERS / "small.yaml")


@pytest.fixture(scope="session")
def small_photographer():
    """One renderer for every test that photographs the small scene's camera."""
    from vision_cal.world.photo import Photographer

    return Photographer(size_px=SMALL.camera.size_px, K=ds.photographer_K(SMALL))


@pytest.fixture(scope="module")
def series(tmp_path_factory, small_photographer):
    out = tmp_path_factory.mktemp("render") / "series"
    return ds.render_dataset(SMALL, out, pilot=pilot_params, photographer=small_photographer)


def _read(folder, name):
    return json.loads((Path(folder) / name).read_text())


def _sheet_of(scene):
    s = scene.sheet
    return make_sheet(size_mm=s.size_mm, bottom_left_mm=s.bottom_left_mm, dictionary=s.dictionary,
                      marker_mm=s.marker_mm, grid=s.grid, margin_mm=s.margin_mm)


@pytest.mark.render
def test_series_is_a_valid_dataset(series):
    s = load_session(series)
    n = SMALL.plan.n_calibration + SMALL.plan.n_validation
    assert len(s.marks) == n
    assert sum(m.role == "validation" for m in s.marks) == SMALL.plan.n_validation
    ids = [m.id for m in s.marks]
    assert len(s.images) == n
    for k, im in enumerate(s.images):
        assert list(im.marks) == ids[:k + 1]
        img = cv2.imread(str(series / im.file), cv2.IMREAD_COLOR)
        assert img is not None and img.shape == (600, 800, 3)
    # what a real user knows, and nothing more
    assert s.robot.params == SMALL.robot.nominal.params
    assert s.camera is not None and s.camera.size_px == (800, 600)
    raw = _read(series, "session.json")
    for m in raw["marks"]:
        assert set(m) <= {"id", "joints_deg", "approach", "role"}
    assert "truth" not in json.dumps(raw) and "effects" not in raw


@pytest.mark.render
def test_truth_has_every_mark_and_pose(series):
    s = load_session(series)
    t = _read(series, "truth.json")
    assert set(t["marks"]) == {m.id for m in s.marks}
    assert t["params"] == SMALL.robot.truth.to_json()
    assert t["effects"] == [e.to_json() for e in SMALL.robot.effects]
    assert set(t["camera"]["T_cam_sheet"]) == {im.file for im in s.images}
    K = np.array(t["camera"]["K"])
    np.testing.assert_allclose(K, s.camera.K)
    # truth marks = the true robot at the commanded joints, within the repeatability
    q = s.joints_deg
    pred = RobotModel(SMALL.robot.truth, SMALL.robot.effects).predict(
        q, np.array(list(t["approach"].values())))
    xy = np.array([t["marks"][m.id] for m in s.marks])
    assert np.max(np.abs(xy - pred)) < 6 * SMALL.robot.repeatability_mm
    # small.yaml's nominal is close to the truth: every mark on free paper
    assert t["off_paper"] == [] and t["on_marker"] == []
    # the kinematic world honours the planned approach
    np.testing.assert_array_equal(np.array(list(t["approach"].values())), s.approach)
    # the stored pose is the one the photo was taken from: a marker's black border is
    # dark where T_cam_sheet puts it, its white quiet zone bright
    sheet = _sheet_of(SMALL)
    dark, bright = [], []
    for im in s.images:
        T = np.array(t["camera"]["T_cam_sheet"][im.file])
        gray = cv2.imread(str(series / im.file), cv2.IMREAD_GRAYSCALE).astype(float)
        for m in sheet.markers[::7]:
            tl = np.asarray(m.corners_mm)[0]                      # top-left, y up
            s_mm = m.corners_mm[1][0] - tl[0]
            mod = s_mm / 7                                        # 5x5 bits + black border
            border = tl + np.array([mod / 2, -s_mm / 2])           # left border column
            quiet = tl + np.array([-mod, -s_mm / 2])               # quiet zone beside it
            (u1, v1), (u2, v2) = project(np.array([border, quiet]), K=K, T_cam_sheet=T)
            dark.append(gray[int(round(v1)), int(round(u1))])
            bright.append(gray[int(round(v2)), int(round(u2))])
    assert np.median(bright) - np.median(dark) > 80


def test_incremental_texture_equals_a_fresh_one():
    sheet = make_sheet(size_mm=(120.0, 80.0), bottom_left_mm=(-60.0, -40.0), marker_mm=20.0,
                       grid=(3, 2), margin_mm=8.0)
    xy = np.array([[-20.0, 5.0], [10.0, -3.0], [33.3, 12.7], [-45.0, -30.0]])
    d = np.array([1.2, 1.5, 1.0, 1.2])
    tex = ds.Textures(sheet, xy, d, px_per_mm=4.0, seed=11)
    for k in (0, 1, 3, 4):
        want = sheet_texture(sheet, marks_xy_mm=xy[:k], mark_diameters_mm=d[:k], px_per_mm=4.0,
                             rng=np.random.default_rng(11))
        np.testing.assert_array_equal(tex.add_marks(k), want)


def test_textures_built_once_equal_two_builds():
    """The finished and the mark-free sheet from one build (what every photo of a dataset
    shares) are the bytes two separate builds give."""
    sheet = make_sheet(size_mm=(120.0, 80.0), bottom_left_mm=(-60.0, -40.0), marker_mm=20.0,
                       grid=(3, 2), margin_mm=8.0)
    xy = np.array([[-20.0, 5.0], [10.0, -3.0], [33.3, 12.7]])
    full, bare = ds.build_textures(sheet, xy, np.full(3, 1.2), px_per_mm=4.0, seed=5)
    np.testing.assert_array_equal(full, sheet_texture(sheet, marks_xy_mm=xy, px_per_mm=4.0,
                                                      rng=np.random.default_rng(5)))
    np.testing.assert_array_equal(bare, sheet_texture(sheet, marks_xy_mm=np.zeros((0, 2)),
                                                      px_per_mm=4.0,
                                                      rng=np.random.default_rng(5)))
    assert np.any(full != bare)
    # the shared mark-free texture is never patched by the photos that use it
    tex = ds.Textures(sheet, xy, np.full(3, 1.2), px_per_mm=4.0, seed=5, built=(full, bare))
    tex.add_marks(3)
    np.testing.assert_array_equal(tex.current, full)
    assert np.any(bare != full)


@pytest.mark.render
def test_single_photo_undeclared_lens_jpeg_and_extras(tmp_path, small_photographer):
    from dataclasses import replace

    from vision_cal.world.scene import ExtraFile

    scene = replace(SMALL,
                    camera=replace(SMALL.camera, dist=(0.05, -0.01, 0.0, 0.0, 0.0),
                                   declared=False),
                    photos=replace(SMALL.photos, mode="single", jpeg_quality=90, arm_parked=True,
                                   extra_files=(ExtraFile("blank.png", "blank"),
                                                ExtraFile("broken.png", "corrupt"))))
    out = ds.render_dataset(scene, tmp_path / "single", pilot=pilot_params, photographer=small_photographer)
    s = load_session(out)
    assert s.camera is None
    ids = tuple(m.id for m in s.marks)
    assert [im.file for im in s.images] == ["img_000.jpg", "blank.png", "broken.png"]
    assert all(im.marks == ids for im in s.images)
    assert (out / "img_000.jpg").read_bytes()[:2] == b"\xff\xd8"
    assert cv2.imread(str(out / "img_000.jpg")).shape == (600, 800, 3)
    assert cv2.imread(str(out / "blank.png")) is not None
    assert cv2.imread(str(out / "broken.png")) is None
    t = _read(out, "truth.json")
    assert t["effects"][-1] == {"name": "lens_distortion", "model": "opencv",
                                "coefficients": [0.05, -0.01, 0.0, 0.0, 0.0]}
    assert t["camera"]["dist"] == [0.05, -0.01, 0.0, 0.0, 0.0]
    assert list(t["arm_parked_q_deg"]) == ["img_000.jpg"]
    assert set(t["extra_files"]) == {"blank.png", "broken.png"}


def test_nothing_half_written_when_rendering_fails(tmp_path, monkeypatch):
    calls = []

    class Boom:
        def photograph(self, tex, **kw):
            calls.append(1)
            if len(calls) == 3:
                raise RuntimeError("renderer crashed")
            return np.zeros((600, 800, 3), np.uint8)

    parent = tmp_path / "p"
    parent.mkdir()
    with pytest.raises(RuntimeError, match="crashed"):
        ds.render_dataset(SMALL, parent / "out", pilot=pilot_params, photographer=Boom())
    assert len(calls) == 3
    assert list(parent.iterdir()) == []
    # an existing dataset survives a failed re-render untouched
    (parent / "out").mkdir()
    (parent / "out" / "session.json").write_text("{}")
    calls.clear()
    with pytest.raises(RuntimeError):
        ds.render_dataset(SMALL, parent / "out", pilot=pilot_params, photographer=Boom())
    assert sorted(p.name for p in parent.iterdir()) == ["out"]
    assert (parent / "out" / "session.json").read_text() == "{}"


def test_refuses_to_replace_a_folder_that_is_not_a_dataset(tmp_path):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "thesis.tex").write_text("x")
    with pytest.raises(VisionCalError, match="not a dataset folder"):
        ds.render_dataset(SMALL, tmp_path / "mine", pilot=pilot_params, photographer=object())
    assert (tmp_path / "mine" / "thesis.tex").exists()


class _Flat:
    """A stand-in photographer (no pyrender): a plain grey image."""

    def photograph(self, tex, **kw):
        return np.full((600, 800, 3), 200, np.uint8)


def test_replaces_a_previous_dataset(tmp_path):
    out = tmp_path / "d"
    ds.render_dataset(SMALL.with_overrides(mode="single"), out, pilot=pilot_params, photographer=_Flat())
    assert len(load_session(out).images) == 1
    ds.render_dataset(SMALL, out, pilot=pilot_params, photographer=_Flat())
    assert len(load_session(out).images) == 10
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d"]


def test_paper_plan_scene(tmp_path):
    scene = load_scene(RENDERS / "paper.yaml")
    from dataclasses import replace

    scene = replace(scene, camera=replace(scene.camera, size_px=(600, 800), f_px=867.0),
                    photos=replace(scene.photos, texture_px_per_mm=1.0))
    out = ds.render_dataset(scene, tmp_path / "p", pilot=pilot_params, photographer=_Flat())
    s = load_session(out)
    assert [m.id for m in s.marks] == ["c00", "j1p", "j1n", "j2p", "j2n"]
    assert _read(out, "truth.json")["off_paper"] == []


def test_cli_render(tmp_path, monkeypatch, capsys):
    from vision_cal.commands.main import main

    # render_dataset looks Photographer up in its own module (imported by name from
    # render.photo): patching render.photo would leave the real pyrender one in place
    built = []
    monkeypatch.setattr(ds, "Photographer", lambda **kw: built.append(kw) or _Flat())
    out = tmp_path / "cli"
    rc = main(["render", str(RENDERS / "small.yaml"), "--out", str(out), "--seed", "5",
               "--mode", "single", "-q"])
    assert rc == 0
    assert capsys.readouterr().out.strip() == str(out.absolute())
    assert _read(out, "truth.json")["seed"] == 5
    assert len(load_session(out).images) == 1
    assert len(built) == 1  # the stand-in, not pyrender, took the photo
    rc = main(["render", str(tmp_path / "nope.yaml"), "--out", str(out)])
    assert rc == 2
    assert "nope.yaml" in capsys.readouterr().err


def test_photographer_K_widens_only_for_barrel_lenses():
    from dataclasses import replace

    from vision_cal.world.camera import camera_matrix

    K = camera_matrix(size_px=SMALL.camera.size_px, f_px=SMALL.camera.f_px)
    np.testing.assert_array_equal(ds.photographer_K(SMALL), K)
    pin = replace(SMALL, camera=replace(SMALL.camera, dist=(0.06, -0.01, 0.0, 0.0, 0.0)))
    np.testing.assert_array_equal(ds.photographer_K(pin), K)
    barrel = replace(SMALL, camera=replace(SMALL.camera, dist=(-0.08, 0.02, 0.0, 0.0, 0.0)))
    Ki = ds.photographer_K(barrel)
    assert Ki[0, 0] < K[0, 0] and Ki[0, 0] == Ki[1, 1]
    np.testing.assert_array_equal(Ki[:2, 2], K[:2, 2])
    # every photo pixel's ray falls inside the wider ideal render
    w, h = SMALL.camera.size_px
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1], [w / 2, 0]], float)
    xn = cv2.undistortPoints(corners.reshape(-1, 1, 2), K, np.array(barrel.camera.dist),
                             criteria=(cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100,
                                       1e-12)).reshape(-1, 2)
    uv = xn * Ki[0, 0] + Ki[:2, 2]
    assert np.all(uv >= -0.5) and np.all(uv <= [w - 0.5, h - 0.5])
    # and an undistorted corner needs nearly all of it (not needlessly wide)
    assert np.max(np.abs(uv - Ki[:2, 2]) / [w / 2, h / 2]) > 0.97


def test_photographer_for_another_camera_is_refused(tmp_path):
    class Other(_Flat):
        size_px = (800, 600)
        K = np.eye(3)

    with pytest.raises(VisionCalError, match="another camera"):
        ds.render_dataset(SMALL, tmp_path / "x", pilot=pilot_params, photographer=Other())
    assert list(tmp_path.iterdir()) == []


def test_simulated_controller_scene(tmp_path):
    from dataclasses import replace

    scene = replace(SMALL, robot=replace(SMALL.robot, controller="smc", repeatability_mm=0.0))
    out = ds.render_dataset(scene, tmp_path / "sim", pilot=pilot_params, photographer=_Flat())
    t = _read(out, "truth.json")
    assert t["controller"] == "smc"
    assert t["effects"] == [{"name": "joint_backlash", "joint": 2, "deg": 0.1}]
    s = load_session(out)
    kin = RobotModel(SMALL.robot.truth, SMALL.robot.effects).predict(s.joints_deg, s.approach)
    xy = np.array([t["marks"][m.id] for m in s.marks])
    assert np.max(np.linalg.norm(xy - kin, axis=1)) < 0.005
    # the links really lag: the reached joint 2 differs from the command by half the band
    lag = np.array([t["link_q_deg"][m.id] for m in s.marks]) - s.joints_deg
    np.testing.assert_allclose(np.abs(lag[:, 1]), 0.05, atol=0.002)


@pytest.mark.render
def test_parallel_render_is_bit_identical_and_reports_its_stage(tmp_path, capsys):
    """--jobs 2 (two processes, one renderer each) writes the same bytes as one process;
    with progress on and stderr not a terminal, each render is one line with its count
    and time."""
    import hashlib

    from dataclasses import replace

    sc = replace(SMALL, plan=replace(SMALL.plan, n_calibration=5, n_validation=1))
    a = ds.render_dataset(sc, tmp_path / "serial", pilot=pilot_params, jobs=1, progress=True)
    b = ds.render_dataset(sc, tmp_path / "parallel", pilot=pilot_params, jobs=2)

    def digest(folder):
        return {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
                for p in sorted(folder.iterdir())}

    da, db = digest(a), digest(b)
    assert len(da) == 8 and da == db   # 6 photos, session.json, truth.json
    err = capsys.readouterr().err
    assert "vision-cal: progress: render serial: 6 photos (1 job(s)) ..." in err, err
    assert "vision-cal: progress: render serial: 6/6 photos in " in err, err


def test_shrunk_sheet_is_photographed_shrunk(tmp_path):
    """sheet_affine is paper that shrank after printing: the photographer sees the printed
    point p at inv(matrix) p in the arm frame (0.3 % closer to the origin along x), the
    marks are drawn into the texture at matrix @ pen, and truth.json's T_cam_sheet maps
    printed points to the camera (so it carries the shrink)."""
    from dataclasses import replace

    from vision_cal.model.robot import SheetAffine

    seen = []

    class Spy(_Flat):
        def photograph(self, tex, **kw):
            seen.append(np.asarray(kw["T_cam_sheet"], float))
            return super().photograph(tex, **kw)

    M = ((1.003, 0.0), (0.0, 1.0))
    scene = replace(SMALL, robot=replace(SMALL.robot, controller="kinematic",
                                         effects=(SheetAffine(M),), repeatability_mm=0.0))
    out = ds.render_dataset(scene.with_overrides(mode="single"), tmp_path / "s",
                            pilot=pilot_params, photographer=Spy())
    (T,) = seen
    # columns of the rotation part: printed x is shrunk by 1/1.003, y untouched
    np.testing.assert_allclose(np.linalg.norm(T[:3, :3], axis=0), [1 / 1.003, 1.0, 1.0],
                               atol=1e-12)
    t = _read(out, "truth.json")
    np.testing.assert_allclose(t["camera"]["T_cam_sheet"]["img_000.png"], T)
    # the marks in truth.json are printed coordinates: x read 1.003 times the arm's
    s = load_session(out)
    arm = scene.robot.true_robot.without_backlash()
    xy_arm = arm.arm_points(arm.link_deg(s.joints_deg, s.approach))[:, 2]
    xy = np.array([t["marks"][m.id] for m in s.marks])
    np.testing.assert_allclose(xy[:, 0], 1.003 * xy_arm[:, 0], atol=1e-9)
    np.testing.assert_allclose(xy[:, 1], xy_arm[:, 1], atol=1e-9)


def test_pilot_calibrator_is_passed_in(tmp_path):
    """The world draws the pilot marks; the calibration of them comes from the caller
    (the renderer does not import the estimator)."""
    seen = []

    def pilot(q_deg, xy_mm):
        seen.append((np.asarray(q_deg), np.asarray(xy_mm)))
        return pilot_params(q_deg, xy_mm)

    with pytest.raises(VisionCalError, match="pilot"):
        ds.render_dataset(SMALL, tmp_path / "none", photographer=_Flat())
    assert not (tmp_path / "none").exists()
    ds.render_dataset(SMALL.with_overrides(mode="single"), tmp_path / "p", pilot=pilot,
                      photographer=_Flat())
    ((q, xy),) = seen
    np.testing.assert_array_equal(q, [[0, 0], [20, 0], [-20, 0], [0, 60], [0, -60]])
    assert xy.shape == (5, 2)
