"""A camera on any arm's flange used (issue 40): ``vision-cal locate`` at a flange pose (the
pixel's ray on the board's plane or the robot's, its std from the calibration's covariance
and the robot's pose error), ``valid_for.flange_poses``, and ``export --opencv --ros``; on
the six-axis world's projected corners (worlds/six_axis.py; no photos rendered)."""

from __future__ import annotations

import csv
import io
import json
from dataclasses import replace
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from tests.camera.handeye_helpers import from_fit
from vision_cal.camera.handeye import fit_handeye
from vision_cal.camera.handeye_document import photos_document
from vision_cal.camera.handeye_locate import FlangeCamera, locate_at
from vision_cal.camera.handeye_lsq import View, _small_T, compose, lens_vector
from vision_cal.camera.handeye_verdict import judge_handeye, limited_by
from vision_cal.commands.main import main
from vision_cal.config import DEFAULT
from worlds.six_axis import Lens, make_world, observe, pose_yaml, shots

#: a small lens: the corners' pixels are what matter here, not their count
LENS = Lens(np.array([[900.0, 0.0, 322.0], [0.0, 900.0, 238.0], [0.0, 0.0, 1.0]]),
            np.array([-0.12, 0.08, 4e-4, -3e-4, 0.0]), (640, 480))
DECLARED = (LENS.K, LENS.dist)


def _session(seed: int, n: int = 10, fresh: int = 6, **kw):
    w = make_world(seed, mount="arm", lens=LENS, joint_noise_deg=0.02, **kw)
    rng = np.random.default_rng(seed + 1)
    sh = shots(w, n + fresh, seed)
    views = [View(s.name, s.T_robot_flange, *observe(w, s, rng), joints_deg=s.q_deg)
             for s in sh]
    return w, sh, views[:n]


def test_the_std_is_the_derivative_of_the_located_point():
    """The located point's std: its analytic derivatives by T_flange_camera, T_robot_board,
    the lens and the flange's error (implicit in the hand-eye's own forward model) against
    locating again with each perturbed, on both planes and off them."""
    w = make_world(5, mount="arm", lens=LENS)
    s = shots(w, 1, 5)[0]
    free = np.array([True] * 6 + [False] * 3)
    P = 12 + int(free.sum())
    cam = FlangeCamera(w.X, w.Y, lens_vector(LENS.K, LENS.dist), free, LENS.size_px,
                       np.eye(P), np.ones(6), "estimated", ())
    uv = np.array([[300.0, 200.0], [80.0, 420.0]])
    for plane, z in (("board", 0.0), ("board", 40.0), ("robot", -20.0)):
        base = [p.robot_std_mm for p in locate_at(cam, s.T_robot_flange, uv, z, plane=plane)]
        J = np.zeros((2, 3, P + 6))
        for k in range(P + 6):
            h = 1e-5 if not 12 <= k < P else 1e-7 * max(1.0, abs(cam.lens[free][k - 12]))
            out = []
            for sg in (1.0, -1.0):
                d = np.zeros(P + 6)
                d[k] = sg * h
                lens = cam.lens.copy()
                lens[free] += d[12:P]
                c = replace(cam, X=compose(cam.X, d[:6]), Y=compose(cam.Y, d[6:12]), lens=lens)
                F = s.T_robot_flange @ _small_T(d[P:][None])[0]
                out.append([p.robot_mm for p in locate_at(c, F, uv, z, plane=plane)])
            J[:, :, k] = (np.array(out[0]) - np.array(out[1])) / (2 * h)
        num = np.sqrt(np.sum(J ** 2, axis=2))         # the covariance is the identity
        assert np.allclose(base, num, rtol=1e-3), (plane, z, base, num)


@pytest.fixture(scope="module")
def fitted():
    """Three worlds, each calibrated from ten photos (the lens declared: the fit is what is
    tested, not the lens's model choice)."""
    out = []
    for seed in (61, 62, 63):
        w, sh, views = _session(seed)
        out.append((w, sh, fit_handeye(views, "arm", LENS.size_px, lens=DECLARED)))
    return out


def test_located_corners_land_within_their_std(fitted):
    """Fresh photos of the world's board (projected corners, the pixel exact) located on the
    board's plane from the flange pose the controller reported: the error against the
    board's true corners, over its stated std, is a unit normal (the 95 % ellipse per point
    holds 85 % or more of them, and the mean squared error per axis is within 2x of 1)."""
    d2 = []
    for w, sh, f in fitted:
        cam = from_fit(f)
        for s in sh[len(f.views):]:
            C = w.board.corners()[[0, 11, 23]]
            P = C @ s.T_camera_board[:3, :3].T + s.T_camera_board[:3, 3]
            for q, c in zip(locate_at(cam, s.T_robot_flange, LENS.project(P), 0.0,
                                      joints=s.q_deg), C):
                truth = w.Y[:3, :3] @ c + w.Y[:3, 3]
                # x and y: the board lies flat (its height is the z std's)
                d2.append((q.robot_mm - truth)[:2] / q.robot_std_mm[:2])
    z = np.array(d2)
    inside = np.mean(np.sum(z ** 2, axis=1) <= 5.99)     # chi-square(2) at 95 %
    assert inside >= 0.85 and np.mean(z ** 2) <= 2.0, (inside, np.mean(z ** 2))


def _document(f, tmp_path, name="cal"):
    board = SimpleNamespace(path=tmp_path / "board.json", kind="saddle", describe=lambda: "b")
    req = SimpleNamespace(robot_poses=str(tmp_path / "poses"))
    cfg = DEFAULT.handeye_photos
    doc = photos_document(f, judge_handeye(f), board=board, req=req, units="m", skipped=[],
                          limit=limited_by(f, cfg))
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps(doc))
    return path, doc


def _pose_args(T) -> list[str]:
    q = Rotation.from_matrix(T[:3, :3]).as_quat()
    return [f"{v:.10g}" for v in (*T[:3, 3], *q)]


def test_locate_and_export_a_six_axis_arms_camera(fitted, tmp_path, capsys):
    """calibration.json of the arm mount: locate at --flange-pose (the point and its std as
    the library says), at --photo, a CSV with a photo column and --robot-poses; a pose far
    from every photo's not located without --force; metres refused; export round-trips."""
    w, sh, f = fitted[0]
    cal, doc = _document(f, tmp_path)
    s = sh[len(f.views)]
    uv = LENS.project((w.board.corners() @ s.T_camera_board[:3, :3].T
                       + s.T_camera_board[:3, 3])[:1])[0]
    want = locate_at(from_fit(f), s.T_robot_flange, [uv], 5.0, joints=s.q_deg)[0]
    args = ["locate", str(cal), "--pixel", f"{uv[0]:.6f}", f"{uv[1]:.6f}", "--z-mm", "5",
            "--flange-pose", *_pose_args(s.T_robot_flange), "--joints",
            *[f"{q:.10g}" for q in s.q_deg]]
    assert main(args) == 0
    out = capsys.readouterr().out
    xyz = [float(v) for v in out.split("robot frame: ")[1].split("mm")[0].split()[1::2]]
    assert np.allclose(xyz, want.robot_mm, atol=1e-3), (out, want.robot_mm)
    assert f"{want.robot_std_mm[2]:.4f}" in out
    # the calibration's own photo, and a folder of pose files with a CSV's photo column
    assert main(["locate", str(cal), "--pixel", "320", "240", "--photo", f.views[2].name]) == 0
    (tmp_path / "poses").mkdir()
    for x in sh:
        (tmp_path / "poses" / f"{x.name}.yaml").write_text(pose_yaml(x.T_robot_flange, x.q_deg))
    far = s.q_deg.copy()
    far[5] += 170.0        # the same flange pose, the wrist half a turn away: not seen
    (tmp_path / "poses" / "far.yaml").write_text(pose_yaml(s.T_robot_flange, far))
    (tmp_path / "px.csv").write_text(f"id,u_px,v_px,photo\na,{uv[0]},{uv[1]},{s.name}\n"
                                     f"b,320,240,{sh[0].name}\nc,320,240,far\n")
    capsys.readouterr()
    assert main(["locate", str(cal), "--csv", str(tmp_path / "px.csv"), "--robot-poses",
                 str(tmp_path / "poses"), "--plane", "robot", "--z-mm", "0"]) == 3
    rows = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    assert [r["flange_pose"] for r in rows] == [s.name, sh[0].name, "far"]
    assert [r["status"] for r in rows] == ["ok", "ok", "outside valid_for"]
    assert float(rows[0]["robot_z_mm"]) == 0.0 and rows[2]["x_mm"] == ""
    assert "valid_for.flange_pose" in rows[2]["reason"]
    # a single pixel far from every photo: not located
    bad = args[:-6] + [f"{q:.10g}" for q in far]
    assert main(bad) == 1
    assert "valid_for.flange_pose" in capsys.readouterr().err
    assert main(bad + ["--force"]) == 0
    assert "outside valid_for" in capsys.readouterr().err
    # the pose in metres
    T = s.T_robot_flange.copy()
    T[:3, 3] /= 1000.0
    assert main(["locate", str(cal), "--pixel", "320", "240", "--flange-pose",
                 *_pose_args(T)]) == 2
    assert "in metres" in capsys.readouterr().err
    # export: T_flange_camera and the ROS static transform from the flange
    assert main(["export", str(cal), "--opencv", str(tmp_path / "c.yaml"), "--ros",
                 str(tmp_path / "r.yaml")]) == 0
    fs = cv2.FileStorage(str(tmp_path / "c.yaml"), cv2.FILE_STORAGE_READ)
    assert np.allclose(fs.getNode("T_flange_camera").mat(), f.X, atol=1e-9)
    assert np.allclose(fs.getNode("T_robot_board").mat(), f.Y, atol=1e-9)
    assert np.allclose(fs.getNode("camera_matrix").mat(), LENS.K, atol=1e-9)
    tr = yaml.safe_load((tmp_path / "r.transform.yaml").read_text())
    assert tr["parent_frame"] == "tool0"
    R = Rotation.from_quat(tr["rotation_xyzw"]).as_matrix()
    assert np.allclose(R, f.X[:3, :3], atol=1e-8)
    assert np.allclose(np.array(tr["translation_m"]) * 1000.0, f.X[:3, 3], atol=1e-6)
    assert np.allclose(tr["std"]["translation_mm"], f.std[3:6])


def test_other_cameras_refuse_a_flange_pose(fitted, tmp_path, capsys):
    """A still camera takes no flange pose; an arm camera needs one (or --photo)."""
    w, sh, f = fitted[1]
    cal, _ = _document(f, tmp_path)
    assert main(["locate", str(cal), "--pixel", "320", "240"]) == 2
    assert "--flange-pose" in capsys.readouterr().err
    still = make_world(7, mount="fixed", lens=LENS, joint_noise_deg=0.02)
    rng = np.random.default_rng(8)
    views = [View(x.name, x.T_robot_flange, *observe(still, x, rng)) for x in shots(still, 6, 7)]
    cal2, _ = _document(fit_handeye(views, "fixed", LENS.size_px, lens=DECLARED), tmp_path,
                        "still")
    assert main(["locate", str(cal2), "--pixel", "320", "240", "--flange-pose",
                 *_pose_args(sh[0].T_robot_flange)]) == 2
    assert "not on a six-axis arm's flange" in capsys.readouterr().err
