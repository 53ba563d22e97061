"""One validator for a camera block (issue 29, section 3): `locate`, `export`, `verify` and
`handeye` refuse a bad one in one line naming the file and the field, exit 2. Hand-made
calibration.json files (no rendering)."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from tests.test_verify_refuses import CHECK, _doc
from vision_cal.commands.main import main

K = [[1300.0, 0.0, 599.5], [0.0, 1300.0, 449.5], [0.0, 0.0, 1.0]]


def _down(z_mm=800.0, x_mm=-300.0, y_mm=-100.0):
    T = np.diag([1.0, -1.0, -1.0, 1.0])               # looking down at the sheet
    T[:3, 3] = [x_mm, y_mm, z_mm]
    return T.tolist()


def _still() -> dict:
    doc = _doc()
    doc["cameras"] = [{
        "images": ["a.png", "b.png"], "size_px": [1200, 900], "K": K, "dist": [0.01, 0, 0, 0, 0],
        "T_robot_camera": _down(), "intrinsics": "declared",
        "T_robot_camera_std": {"rotation_deg": [0.01] * 3, "translation_mm": [0.05] * 3},
        "covariance": {"params": ["rot_x_deg", "rot_y_deg", "rot_z_deg", "x_mm", "y_mm", "z_mm",
                                  "f_px"], "matrix": np.diag([1e-4] * 3 + [2.5e-3] * 3 + [0])
                       .tolist()},
        "corner_rms_px": 0.1, "n_corners": 400,
        "robot_to_sheet": {"z1_deg": -2.57, "base_mm": [-424.26, -230.35],
                           "sheet_matrix": [[1.0, 0.0], [0.0, 1.0]]}}]
    return doc


def _arm() -> dict:
    doc = _doc()
    doc["method"] = "arm_camera"
    X = np.diag([1.0, -1.0, -1.0, 1.0])
    X[:3, 3] = [20.0, 5.0, 190.0]
    doc["cameras"] = [{"images": ["p0.png"], "size_px": [1200, 900], "K": K, "dist": [0] * 5,
                       "T_flange_camera": X.tolist(), "mount": "flange",
                       "T_flange_camera_std": {"rotation_deg": [0.01] * 3,
                                               "translation_mm": [0.02] * 3},
                       "intrinsics": "declared"}]
    doc["covariance"] = {"matrix": (np.eye(12) * 1e-6).tolist()}
    doc["verdict"]["repeatability_mm"] = 0.01
    return doc


def _set(path, value):
    def edit(d):
        *head, last = path
        for k in head:
            d = d[k]
        d[last] = value
    return edit


def _T(fn):
    def edit(d):
        T = np.array(d["cameras"][0]["T_robot_camera"])
        d["cameras"][0]["T_robot_camera"] = fn(T).tolist()
    return edit


def _metres(T):
    T[:3, 3] /= 1000.0
    return T


def _scaled(T):
    T[:3, :3] *= 1.2
    return T


BAD_STILL = [
    (_set(["cameras", 0, "K", 0, 0], -1300.0), "cameras[0].K[0][0]", "positive focal"),
    (_set(["cameras", 0, "K", 0, 2], 5000.0), "cameras[0].K", "principal point"),
    (_set(["cameras", 0, "K", 1, 1], float("nan")), "cameras[0].K[1][1]", "finite"),
    (_set(["cameras", 0, "dist"], [0.0, 0.0, 0.0]), "cameras[0].dist", "4, 5, 8, 12 or 14"),
    (_set(["cameras", 0, "dist", 0], 1e6), "cameras[0].dist[0]", "distortion"),
    (_T(_metres), "cameras[0].T_robot_camera", "metres"),
    (_T(_scaled), "cameras[0].T_robot_camera", "not a rotation"),
    (_set(["cameras", 0, "covariance", "matrix", 3, 3], float("nan")),
     "cameras[0].covariance.matrix[3][3]", "finite"),
    (_set(["cameras", 0, "covariance", "matrix", 3, 3], -1e-3),
     "cameras[0].covariance.matrix", "positive semi-definite"),
    (_set(["cameras", 0, "covariance", "matrix", 3, 4], 1e-3),
     "cameras[0].covariance.matrix", "not symmetric"),
    (_set(["cameras", 0, "T_robot_camera_std", "translation_mm", 0], -1.0),
     "cameras[0].T_robot_camera_std.translation_mm[0]", "standard deviation"),
    (_set(["cameras", 0, "robot_to_sheet", "sheet_matrix"], [[1.0, 0.0], [0.0, 0.0]]),
     "cameras[0].robot_to_sheet.sheet_matrix", "determinant"),
]


def _write(tmp_path, doc) -> Path:
    p = tmp_path / "calibration.json"
    p.write_text(json.dumps(doc))
    return p


def _one_line(capsys, rc, path, field, says):
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert f"{path}: {field}: " in err[0] and says in err[0], err[0]


def test_the_good_blocks_pass(tmp_path, capsys):
    assert main(["locate", str(_write(tmp_path, _still())), "--pixel", "600", "450"]) == 0
    assert "robot frame" in capsys.readouterr().out
    assert main(["export", str(_write(tmp_path, _still())), "--opencv",
                 str(tmp_path / "cam.yaml"), "-q"]) == 0
    assert main(["locate", str(_write(tmp_path, _arm())), "--pixel", "600", "450",
                 "--joints", "10", "20"]) == 0


@pytest.mark.parametrize("edit, field, says", BAD_STILL)
def test_locate_and_export_refuse_a_bad_still_camera(tmp_path, capsys, edit, field, says):
    doc = copy.deepcopy(_still())
    edit(doc)
    path = _write(tmp_path, doc)
    _one_line(capsys, main(["locate", str(path), "--pixel", "600", "450"]), path, field, says)
    out = tmp_path / "cam.yaml"
    _one_line(capsys, main(["export", str(path), "--opencv", str(out), "-q"]), path, field, says)
    assert not out.exists()


@pytest.mark.parametrize("edit, field, says", [BAD_STILL[1], BAD_STILL[5], BAD_STILL[8]])
def test_verify_refuses_a_bad_still_camera(tmp_path, capsys, edit, field, says):
    doc = copy.deepcopy(_still())
    edit(doc)
    path = _write(tmp_path, doc)
    _one_line(capsys, main(["verify", str(path), str(CHECK), "--out", str(tmp_path / "v"),
                            "-q"]), path, field, says)


def _flange(fn):
    def edit(d):
        T = np.array(d["cameras"][0]["T_flange_camera"])
        d["cameras"][0]["T_flange_camera"] = fn(T).tolist()
    return edit


@pytest.mark.parametrize("edit, field, says", [
    (_flange(_metres), "cameras[0].T_flange_camera", "metres"),
    (_flange(_scaled), "cameras[0].T_flange_camera", "not a rotation"),
    (_set(["covariance", "matrix", 0, 0], -1.0), "covariance.matrix", "positive semi-definite"),
    (_set(["cameras", 0, "dist"], [0.0] * 6), "cameras[0].dist", "4, 5, 8, 12 or 14"),
])
def test_locate_refuses_a_bad_arm_camera(tmp_path, capsys, edit, field, says):
    doc = copy.deepcopy(_arm())
    edit(doc)
    path = _write(tmp_path, doc)
    _one_line(capsys, main(["locate", str(path), "--pixel", "600", "450", "--joints", "10",
                            "20"]), path, field, says)


@pytest.fixture(scope="module")
def field_sheet(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("field")
    assert main(["sheet", "--size", "A4", "--field", "--out", str(tmp / "field"), "-q"]) == 0
    return json.loads((tmp / "field" / "sheet.json").read_text())


@pytest.mark.parametrize("lens, field, says", [
    ({"size_px": [1200, 900], "K": [[1300, 0, 1599.5], [0, 1300, 449.5], [0, 0, 1]],
      "dist": [0] * 5}, "camera.K", "principal point"),
    ({"size_px": [1200, 900], "K": K, "dist": [0] * 7}, "camera.dist", "4, 5, 8, 12 or 14"),
    ({"size_px": [1200, 900], "K": K, "dist": [1e6, 0, 0, 0, 0]}, "camera.dist[0]",
     "distortion"),
])
def test_handeye_refuses_a_bad_lens(tmp_path, capsys, field_sheet, lens, field, says):
    folder = tmp_path / "arm"
    folder.mkdir()
    session = {"format": "vision-cal/1", "sheet": field_sheet,
               "robot": {"L1_mm": 350.0, "L2_mm": 260.0, "joint_zero_deg": [0.0, 0.0],
                         "base_mm": [-400.0, -250.0]},
               "camera": lens,
               "poses": [{"image": f"p{i}.png", "joints_deg": [10.0 * i, 30.0], "j4_deg": 0.0}
                         for i in range(6)]}
    (folder / "session.json").write_text(json.dumps(session))
    rc = main(["handeye", str(folder), "--out", str(tmp_path / "out"), "-q"])
    _one_line(capsys, rc, folder / "session.json", field, says)
