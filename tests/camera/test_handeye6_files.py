"""What ``vision-cal handeye PHOTOS/ --robot-poses POSES --sheet BOARD`` reads (issue 40):
the robot's poses (per-photo YAML in metres, or a CSV in mm) with their units checked, the
ChArUco board of ``vision-cal sheet --charuco`` and its sheet.json, the board's saddles
found in a photo, and the command's own refusals."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from vision_cal.actions.sheet import SheetRequest, sheet
from vision_cal.camera.board import find_board, load_board
from vision_cal.camera.robot_poses import pair_with_photos, read_robot_poses
from vision_cal.commands.main import main
from vision_cal.errors import VisionCalError
from worlds.six_axis import Lens, make_world, photograph, pose_yaml, shots
from vision_cal.sheet.charuco import charuco_spec

ROOT = Path(__file__).resolve().parents[2]
OPENCV_FIXTURE = ROOT / "fixtures" / "real_charuco_opencv" / "sheet.json"
#: the survey helper's hand-written board of the real six-axis session (merged separately)
INDUSTRIAL_FIXTURE = ROOT / "fixtures" / "industrial_charuco_even" / "sheet.json"


def _pose_files(folder: Path, scale: float = 1.0, n: int = 3) -> Path:
    folder.mkdir()
    w = make_world(1, mount="fixed")
    for s in shots(w, n, 1):
        T = s.T_robot_flange.copy()
        T[:3, 3] *= scale
        (folder / f"{s.name}.yaml").write_text(pose_yaml(T))
    return folder


def test_pose_folder_in_metres_is_read_in_mm(tmp_path):
    poses, units = read_robot_poses(_pose_files(tmp_path / "p"))
    w = make_world(1, mount="fixed")
    T = shots(w, 3, 1)[0].T_robot_flange
    assert units == "m" and np.allclose(poses[0].T, T, atol=1e-9)


def test_pose_folder_in_millimetres_is_refused_naming_it(tmp_path):
    with pytest.raises(VisionCalError, match="the file is in millimetres"):
        read_robot_poses(_pose_files(tmp_path / "p", scale=1000.0))


def test_csv_in_metres_is_refused_naming_it(tmp_path):
    rows = ["photo,x_mm,y_mm,z_mm,qx,qy,qz,qw"]
    for i in range(4):
        rows.append(f"{i}.png,{0.4 + 0.05 * i},{0.1 * i},{0.5},0,0,0,1")
    (tmp_path / "p.csv").write_text("\n".join(rows) + "\n")
    with pytest.raises(VisionCalError, match="lengths are in metres"):
        read_robot_poses(tmp_path / "p.csv")


def test_a_bad_quaternion_and_a_missing_pose_are_named(tmp_path):
    folder = _pose_files(tmp_path / "p")
    (folder / "1.yaml").write_text("x: 0.4\ny: 0.1\nz: 0.5\nqx: 0.5\nqy: 0.5\nqz: 0.5\nqw: 0.0\n")
    with pytest.raises(VisionCalError, match=r"1\.yaml: qx, qy, qz, qw: not a unit quaternion"):
        read_robot_poses(folder)
    poses, _ = read_robot_poses(_pose_files(tmp_path / "q"))
    with pytest.raises(VisionCalError, match=r"no pose for 1 photo\(s\): 7\.png \(needs 7\.yaml"):
        pair_with_photos(poses, ["0.png", "7.png"], "poses/")


def test_ros_pose_messages_are_read(tmp_path):
    d = tmp_path / "p"
    d.mkdir()
    (d / "a.yaml").write_text("position: {x: 0.5, y: 0.0, z: 0.4}\n"
                              "orientation: {x: 0.0, y: 0.0, z: 0.0, w: 1.0}\n")
    (d / "b.yaml").write_text("position: {x: 0.6, y: 0.1, z: 0.4}\n"
                              "orientation: {x: 0.0, y: 0.0, z: 0.7071068, w: 0.7071068}\n")
    poses, _ = read_robot_poses(d)
    assert np.allclose(poses[1].t_mm, [600.0, 100.0, 400.0])
    assert np.allclose(poses[1].T[:3, :3] @ [1, 0, 0], [0, 1, 0], atol=1e-6)


def test_the_arms_joints_are_read_with_the_poses(tmp_path):
    """joints_deg in a pose file and q1_deg... in the CSV (degrees); a pose without them
    when the others have them is refused, naming it."""
    d = tmp_path / "p"
    d.mkdir()
    w = make_world(1, mount="fixed")
    sh = shots(w, 3, 1)
    for s in sh:
        (d / f"{s.name}.yaml").write_text(pose_yaml(s.T_robot_flange, s.q_deg))
    poses, _ = read_robot_poses(d)
    assert np.allclose(poses[2].joints_deg, sh[2].q_deg)
    rows = ["photo,x_mm,y_mm,z_mm,qx,qy,qz,qw,q1_deg,q2_deg"]
    rows += [f"{i},{400 + 50 * i},{10 * i},500,0,0,0,1,{i},{-90 + i}" for i in range(3)]
    (tmp_path / "p.csv").write_text("\n".join(rows) + "\n")
    poses, _ = read_robot_poses(tmp_path / "p.csv")
    assert np.allclose(poses[1].joints_deg, [1.0, -89.0])
    (d / "1.yaml").write_text(pose_yaml(sh[1].T_robot_flange))
    with pytest.raises(VisionCalError, match=r"1\.yaml: joints_deg: the poses list different"):
        read_robot_poses(d)


def _charuco(tmp_path, name, **kw) -> dict:
    args = dict(charuco="5x7", square_mm=40.0, marker_mm=20.0, dictionary="DICT_6X6_250")
    args.update(kw)
    sheet(SheetRequest(out=str(tmp_path / name), quiet=True, **args))
    return json.loads((tmp_path / name / "sheet.json").read_text())


def test_sheet_charuco_is_opencvs_board(tmp_path):
    """`sheet --charuco 5x7 --square-mm 40 --marker-mm 20 --dictionary DICT_6X6_250`: the
    markers of fixtures/real_charuco_opencv (from OpenCV's getObjPoints) to 1e-6 mm, and
    the chessboard corners OpenCV's getChessboardCorners in the sheet frame."""
    doc = _charuco(tmp_path, "b")
    ref = json.loads(OPENCV_FIXTURE.read_text())
    got = {m["id"]: np.array(m["corners_mm"]) for m in doc["markers"]}
    assert set(got) == {m["id"] for m in ref["markers"]}
    for m in ref["markers"]:
        assert np.abs(got[m["id"]] - np.array(m["corners_mm"])).max() < 1e-6
    spec = charuco_spec((5, 7), 40.0, 20.0, "DICT_6X6_250")
    cv = np.asarray(spec.opencv_board().getChessboardCorners(), float)[:, :2]
    assert np.abs(spec.to_sheet(cv) - np.array(doc["charuco"]["corners_mm"])).max() < 1e-4
    board = load_board(tmp_path / "b" / "sheet.json")
    assert board.charuco is not None and board.kind == "saddle"


def test_sheet_charuco_agrees_with_the_survey_fixture(tmp_path):
    """The industrial session's board as its fixture describes it (fixtures/
    industrial_charuco_even/sheet.json, CharucoBoard((5, 7), 36.195, 18.256,
    DICT_6X6_250)) and as `sheet --charuco` writes it: the same markers and corners."""
    if not INDUSTRIAL_FIXTURE.is_file():
        pytest.skip("fixtures/industrial_charuco_even/sheet.json is not merged yet")
    ref = json.loads(INDUSTRIAL_FIXTURE.read_text())
    doc = _charuco(tmp_path, "b", square_mm=36.195, marker_mm=18.256)
    got = {m["id"]: np.array(m["corners_mm"]) for m in doc["markers"]}
    assert set(got) == {m["id"] for m in ref["markers"]}
    for m in ref["markers"]:
        assert np.abs(got[m["id"]] - np.array(m["corners_mm"])).max() < 1e-3
    assert np.abs(np.array(doc["charuco"]["corners_mm"])
                  - np.array(ref["charuco"]["corners_mm"])).max() < 1e-3


def test_legacy_pattern_and_refusals(tmp_path):
    new = _charuco(tmp_path, "n", charuco="6x8")
    old = _charuco(tmp_path, "o", charuco="6x8", legacy_pattern=True)
    assert new["markers"][0]["corners_mm"] != old["markers"][0]["corners_mm"]
    with pytest.raises(VisionCalError, match="--marker-mm: the marker .* smaller"):
        _charuco(tmp_path, "x", marker_mm=45.0)
    with pytest.raises(VisionCalError, match="--dictionary"):
        _charuco(tmp_path, "y", dictionary=None)
    with pytest.raises(VisionCalError, match="--field: does not apply"):
        _charuco(tmp_path, "z", field=True)


def test_a_hand_written_board_that_is_not_opencvs_is_refused(tmp_path):
    doc = _charuco(tmp_path, "b")
    doc["markers"][3]["corners_mm"][0][0] += 0.5
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(VisionCalError, match="marker 3 is not where OpenCV's CharucoBoard"):
        load_board(tmp_path / "bad.json")


def test_saddles_found_in_a_photo(tmp_path):
    """The world's photo of its board (OpenCV's print, its lens): every saddle found, at
    the world's projection within 0.5 px, in the sheet frame of `sheet --charuco`."""
    lens = Lens(np.array([[700.0, 0.0, 320.0], [0.0, 700.0, 240.0], [0.0, 0.0, 1.0]]),
                np.array([-0.1, 0.05, 0.0, 0.0, 0.0]), (640, 480))
    w = make_world(5, mount="fixed", lens=lens)
    s = shots(w, 1, 5)[0]
    img = photograph(w, s.T_camera_board, np.random.default_rng(0))
    _charuco(tmp_path, "b", square_mm=w.board.square_mm, marker_mm=w.board.marker_mm)
    board = load_board(tmp_path / "b" / "sheet.json")
    pts = find_board(img, board)
    assert pts.reason is None and len(pts.ids) == 24
    T = s.T_camera_board
    truth = lens.project(pts.board_mm @ T[:3, :3].T + T[:3, 3])
    assert np.abs(pts.px - truth).max() < 0.5
    other = find_board(np.full_like(img, 200), board)
    assert "too little of the board" in other.reason
    # the same board described by its markers alone (a plain ArUco grid): their corners
    doc = json.loads((tmp_path / "b" / "sheet.json").read_text())
    del doc["charuco"]
    (tmp_path / "grid.json").write_text(json.dumps(doc))
    grid = find_board(img, load_board(tmp_path / "grid.json"))
    assert grid.reason is None and len(grid.ids) >= 4 * 14
    truth = lens.project(grid.board_mm @ T[:3, :3].T + T[:3, 3])
    assert np.sqrt(np.mean(np.sum((grid.px - truth) ** 2, axis=1))) < 0.5


@pytest.mark.parametrize("args,field", [
    (["--sheet", "b.json", "--mount", "fixed"], "FOLDER"),
    (["photos", "--mount", "fixed"], "--sheet"),
    (["photos", "--sheet", "b.json"], "--mount"),
    (["photos", "--sheet", "b.json", "--mount", "fixed", "--units", "m"], "--units"),
    (["photos", "--sheet", "b.json", "--mount", "fixed", "--poses", "p.json"], "--robot-poses"),
])
def test_the_command_refuses_what_does_not_go_together(args, field, tmp_path, capsys):
    code = main(["handeye", "--robot-poses", "poses", "--out", str(tmp_path / "o"), *args])
    assert code == 2 and field in capsys.readouterr().err


def test_the_files_follow_their_schemas(tmp_path):
    """The world's pose files (as ROS tools write them), a ROS Pose message and `sheet
    --charuco`'s sheet.json follow vision_cal/schema; a pose without qw does not."""
    import jsonschema
    import yaml

    from vision_cal.schema import validate

    for p in _pose_files(tmp_path / "p").iterdir():
        validate(yaml.safe_load(p.read_text()), "robot_pose")
    validate({"position": {"x": 0.5, "y": 0, "z": 0.4},
              "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}}, "robot_pose")
    with pytest.raises(jsonschema.ValidationError):
        validate({"x": 0.5, "y": 0, "z": 0.4, "qx": 0, "qy": 0, "qz": 0}, "robot_pose")
    validate(_charuco(tmp_path, "b"), "sheet")


def test_help_shows_the_way_in(capsys):
    """`handeye --help` and `sheet --help` show the photos-and-poses path and the board."""
    for cmd, words in (("handeye", ("--robot-poses", "--sheet", "7.yaml for 7.png",
                                    "T_flange_board")),
                       ("sheet", ("--charuco", "--square-mm", "--legacy-pattern"))):
        with pytest.raises(SystemExit):
            main([cmd, "--help"])
        out = capsys.readouterr().out
        assert all(w in out for w in words), (cmd, [w for w in words if w not in out])


def test_the_declared_lens_is_read_and_checked(tmp_path):
    """--camera: a JSON holding a camera block (session.json's) or the block itself; a
    lens with more than five distortion terms is refused, naming the field."""
    from vision_cal.actions.handeye import HandeyePhotosRequest, declared_lens

    cam = {"size_px": [640, 480], "K": [[700, 0, 320], [0, 700, 240], [0, 0, 1]],
           "dist": [-0.1, 0.05, 0, 0, 0]}
    for i, doc in enumerate(({"camera": cam}, cam)):
        (tmp_path / f"l{i}.json").write_text(json.dumps(doc))
        req = HandeyePhotosRequest(str(tmp_path), "p", "s", "fixed", "o",
                                   camera=str(tmp_path / f"l{i}.json"))
        size, K, dist = declared_lens(req)
        assert size == (640, 480) and K[0, 0] == 700 and dist[0] == -0.1
    (tmp_path / "l8.json").write_text(json.dumps({**cam, "dist": [0, 0, 0, 0, 0, 0.1, 0, 0]}))
    with pytest.raises(VisionCalError, match="camera.dist: only the 5-term lens"):
        declared_lens(HandeyePhotosRequest(str(tmp_path), "p", "s", "fixed", "o",
                                           camera=str(tmp_path / "l8.json")))
