"""Cameras in the robot frame: pixel -> robot accuracy of a still camera (and the arm camera).

Usage: PYOPENGL_PLATFORM=egl .venv/bin/python bench/camera.py [--seeds 77 78] [--out DIR]

Still camera: a rendered series (1600 x 1200 px, one camera pose, tilt 5-15 deg, 20 + 6
marks, the default hidden joint-2 backlash) calibrated as a user would; then, against the
world's truth (truth.json: true z1, base and T_cam_sheet):

- ``plane``: 200 random sheet points projected by the true camera, located at z = 0;
- ``+50 mm``: the same at 50 mm above the sheet (the point is projected from its true 3-D
  place and located with ``--z-mm 50``);
- ``plate +50``: a raised plate rendered by the world's photographer (a 160 x 120 mm card
  of twelve ArUco markers lying 50 mm above the sheet, at five places under the camera,
  photographed by the true camera with its lens and sensor noise); its marker corners
  found by the measurement stage's sub-pixel edge fit and located at ``--z-mm 50``,
  against the corners' true robot-frame place: RMS over the corners (the corner
  detection's own noise is in it, printed in px) and each plate's mean error (that noise
  averaged out over its 48 corners: the mapping's error there);
- ``val marks``: each validation mark's true ink position, projected, located, against
  where the calibrated model says the commanded joints put the pen (robot frame), so
  robot repeatability and model error are in it;
- ``ratio``: RMS of error / predicted std (1 when the std tells the truth).

Both with the lens declared in session.json and with it undeclared (focal length fitted).
Seeds here are not the tests' (41) nor the ones used while writing the code (31).

Arm camera (``--arm``): the world's camera on the true robot (0.01 mm repeatability per
photo) photographs the marker field from 24 poses (1280 x 960 px); ``vision-cal handeye``:

- ``plane`` / ``+50 mm``: for each photo, 20 true points projected by the photo's true
  camera, located through the fitted robot and ``T_flange_camera`` at the commanded joints
  (``camera/arm.camera_for``, as ``vision-cal locate --photo``), against their true
  robot-frame place (the robot's repeatability is in it), and RMS(err/std);
- the verdict (residual over the noise floor);
- kinematics against the pen method: the pen calibration of a rendered series of the same
  true robot, each parameter's difference over the combined std;
- poses needed: the predicted std of the flange position (per axis, RMS over the reachable
  sheet) against the number of poses (projected corners, 0.1 px, 0.01 mm repeatability;
  median of 5 draws), the first below 0.02 mm.
"""

from __future__ import annotations

import argparse
import copy
import time
from pathlib import Path

import cv2
import numpy as np
import yaml

from vision_cal.estimate.paper import pilot_params
from vision_cal.camera.fixed import camera_of, locate
from vision_cal.dataset.io import read_json
from vision_cal.actions.pipeline import calibrate_dataset
from vision_cal.world import dataset as ds
from vision_cal.world.scene import scene_from_dict

ROOT = Path(__file__).resolve().parents[1]


def _still_scene(seed: int, declared: bool):
    d = yaml.safe_load((ROOT / "renders" / "small.yaml").read_text())
    d["seed"] = seed
    d["camera"].update(size_px=[1600, 1200], f_px=1730.0, n_views=1, moving=False,
                       tilt_deg=[5.0, 15.0], declared=declared)
    d["plan"].update(n_calibration=20, n_validation=6)
    d["photos"] = {"mode": "series", "texture_px_per_mm": 4.0}
    return scene_from_dict(copy.deepcopy(d), file=f"bench-still-{seed}")


def _truth_T(truth):
    """True T_sheet_robot from the contract's formula, T_cam_sheet and K."""
    tp = truth["params"]
    z1 = np.radians(tp["joint_zero_deg"][0])
    T_sr = np.array([[np.cos(z1), -np.sin(z1), 0, tp["base_mm"][0]],
                     [np.sin(z1), np.cos(z1), 0, tp["base_mm"][1]], [0, 0, 1, 0], [0, 0, 0, 1]])
    T_cs = np.array(next(iter(truth["camera"]["T_cam_sheet"].values())))
    return T_sr, T_cs, np.array(truth["camera"]["K"]), np.array(truth["camera"]["dist"])


def _project(T_cs, K, dist, p_s):
    p_c = p_s @ T_cs[:3, :3].T + T_cs[:3, 3]
    uv, _ = cv2.projectPoints(p_c.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, dist)
    return uv.reshape(-1, 2)


def still(seed: int, declared: bool, out: Path) -> dict:
    t0 = time.time()
    sc = _still_scene(seed, declared)
    folder = ds.render_dataset(sc, out / f"still-{seed}-{int(declared)}" / "data",
                               pilot=pilot_params)
    run = calibrate_dataset(folder, out_dir=folder.parent / "out")
    truth = read_json(folder / "truth.json")
    cam = camera_of(run.document, 0)
    T_sr, T_cs, K, dist = _truth_T(truth)
    T_rs = np.linalg.inv(T_sr)
    rng = np.random.default_rng(seed)
    res = {"seconds": time.time() - t0, "intrinsics": cam.intrinsics,
           "f_px": cam.K[0, 0], "f_true": K[0, 0], "n_photos": len(cam.images)}
    for name, z in (("plane", 0.0), ("+50 mm", 50.0)):
        p_s = np.column_stack([rng.uniform(-250, 250, 200), rng.uniform(-170, 170, 200),
                               np.full(200, z)])
        if cam.intrinsics == "focal length undetermined" and z:
            res[name] = None
            continue
        got = locate(cam, _project(T_cs, K, dist, p_s), z)
        err = np.array([g.robot_mm[:2] for g in got]) - (p_s @ T_rs[:3, :3].T + T_rs[:3, 3])[:, :2]
        std = np.array([g.robot_std_mm[:2] for g in got])
        e = np.hypot(*err.T)
        res[name] = (np.sqrt(np.mean(e**2)), e.max(), np.sqrt(np.mean((err / std) ** 2)))
    if cam.intrinsics != "focal length undetermined":
        res["plate +50"] = _raised_plate(sc, truth, cam, 50.0, T_rs, rng)
    # validation marks: true ink -> pixel -> robot frame, against the calibrated model
    model = run.model
    z1 = np.radians(model.params.joint_zero_deg[0])
    Rm = np.array([[np.cos(z1), np.sin(z1)], [-np.sin(z1), np.cos(z1)]])
    base = np.asarray(model.params.base_mm)
    Minv = np.linalg.inv(model.sheet_matrix())
    marks = run.document["marks"]
    val = [k for k, v in marks.items() if v["role"] == "validation" and k in truth["marks"]]
    if val:
        ink = np.array([truth["marks"][k] for k in val])
        got = locate(cam, _project(T_cs, K, dist, np.column_stack([ink, np.zeros(len(ink))])), 0)
        q = np.array([marks[k]["joints_deg"] for k in val])
        s = np.array([marks[k]["approach"] for k in val], float)
        fk_r = (model.predict(q, s) @ Minv.T - base) @ Rm.T
        e = np.hypot(*(np.array([g.robot_mm[:2] for g in got]) - fk_r).T)
        res["val marks"] = (np.sqrt(np.mean(e**2)), e.max(), float("nan"))
    return res


def _raised_plate(sc, truth, cam, z_mm, T_rs, rng):
    """The rendered plate's marker corners located at z_mm against their truth: RMS and max
    (mm, 2-D) over the corners, the RMS over plates of each plate's mean error (the corner
    detection's noise averaged out: the mapping's own error there) and the detection's
    2-D RMS error in px against the true projection."""
    from vision_cal.dataset.marker_geometry import marker_geometry
    from vision_cal.measure.aruco import corners_from_edges, edge_points, find_sheet_markers
    from vision_cal.world.photo import Photographer
    from vision_cal.world.sheet import make_sheet, sheet_texture

    _, T_cs, K, dist = _truth_T(truth)
    w, h = sc.camera.size_px
    ph = Photographer(size_px=(w, h), K=K)
    errs, det_px = [], []
    try:
        for cx, cy in ((0, 0), (-150, -90), (150, -90), (-150, 90), (150, 90)):
            plate = make_sheet(size_mm=(160.0, 120.0), bottom_left_mm=(cx - 80.0, cy - 60.0),
                               dictionary="DICT_5X5_100", marker_mm=22.0, grid=(4, 3),
                               margin_mm=10.0)
            tex = sheet_texture(plate, marks_xy_mm=np.zeros((0, 2)), px_per_mm=8.0, rng=rng)
            x0, y0, x1, y1 = plate.extent_mm
            grid = (np.array([x0, x1]), np.array([y0, y1]), np.full((2, 2), z_mm))
            rgb = ph.photograph(tex, extent_mm=plate.extent_mm, T_cam_sheet=T_cs,
                                dist=dist if np.any(dist) else None,
                                K_dist=K if np.any(dist) else None,
                                noise_sigma=sc.photos.noise_sigma, rng=rng, height_grid=grid)
            gray = cv2.cvtColor(np.asarray(rgb), cv2.COLOR_RGB2GRAY)
            det = find_sheet_markers(gray, plate)
            if det.reason:
                continue
            edges = edge_points(gray, det.corners_px, geometry=marker_geometry(plate))
            px = np.asarray(corners_from_edges(edges, det.corners_px), float).reshape(-1, 2)
            mm = np.asarray(det.corners_mm, float).reshape(-1, 2)
            got = locate(cam, px, z_mm)
            p_s = np.column_stack([mm, np.full(len(mm), z_mm)])
            err = (np.array([g.robot_mm[:2] for g in got])
                   - (p_s @ T_rs[:3, :3].T + T_rs[:3, 3])[:, :2])
            errs.append(err)
            det_px.append(px - _project(T_cs, K, dist, p_s))
    finally:
        ph.close()
    if not errs:
        return None
    e = np.hypot(*np.concatenate(errs).T)
    bias = np.array([np.hypot(*er.mean(axis=0)) for er in errs])
    dpx = np.concatenate(det_px)
    return {"rms": np.sqrt(np.mean(e**2)), "max": e.max(), "n": len(e),
            "plate_mean_rms": float(np.sqrt(np.mean(bias**2))),
            "detection_px": float(np.sqrt(np.mean(np.sum(dpx**2, axis=1))))}


def _arm_locate(doc, truth, session, z_mm, rng):
    """Errors (N, 2) mm and their ratio to locate's std: pixel -> robot through the fitted
    arm at each photo's commanded joints (``vision-cal locate --photo``)."""
    from vision_cal.camera.arm import camera_for

    T_sr_true, _, _, _ = _truth_T({"params": truth["params"], "camera": {
        "T_cam_sheet": {"x": np.eye(4)}, "K": np.eye(3), "dist": np.zeros(5)}})
    T_rs = np.linalg.inv(T_sr_true)
    K = np.array(truth["camera"]["K"])
    w, h = session["camera"]["size_px"] if "camera" in session else doc["cameras"][0]["size_px"]
    errs, ratios = [], []
    for pose in doc["poses"]:
        T_cs = np.array(truth["camera"]["T_cam_sheet"][pose["image"]])
        centre = np.linalg.inv(T_cs)[:2, 3]
        p_s = np.column_stack([centre + rng.uniform(-40, 40, (20, 2)), np.full(20, z_mm)])
        uv = _project(T_cs, K, np.zeros(5), p_s)
        ok = (uv[:, 0] > 0) & (uv[:, 0] < w - 1) & (uv[:, 1] > 0) & (uv[:, 1] < h - 1)
        got = locate(camera_for(doc, 0, photo=pose["image"]), uv[ok], z_mm)
        err = np.array([g.robot_mm[:2] for g in got]) - (p_s[ok] @ T_rs[:3, :3].T + T_rs[:3, 3])[:, :2]
        errs.append(err)
        ratios.append(err / np.array([g.robot_std_mm[:2] for g in got]))
    return np.concatenate(errs), np.concatenate(ratios)


def arm(seed: int, out: Path) -> None:
    import json

    from vision_cal.commands.main import main as cli
    from vision_cal.world.arm_camera import render_arm_dataset

    # the pen method on a rendered series of the same true robot (no hidden effect)
    d = yaml.safe_load((ROOT / "renders" / "small.yaml").read_text())
    d["seed"] = seed
    d["robot"]["effects"] = []
    d["camera"].update(size_px=[1600, 1200], f_px=1730.0)
    d["plan"].update(n_calibration=24, n_validation=6)
    d["photos"] = {"mode": "series", "texture_px_per_mm": 4.0}
    sc = scene_from_dict(copy.deepcopy(d), file=f"bench-pen-{seed}")
    pen_folder = ds.render_dataset(sc, out / f"pen-{seed}" / "data", pilot=pilot_params)
    pen = calibrate_dataset(pen_folder, out_dir=pen_folder.parent / "out").document
    truth_params = read_json(pen_folder / "truth.json")["params"]
    nominal = read_json(pen_folder / "session.json")["robot"]
    nominal = {k: nominal[k] for k in ("L1_mm", "L2_mm", "joint_zero_deg", "base_mm")}
    folder = render_arm_dataset(out / f"arm-{seed}" / "data", truth=truth_params,
                                nominal=nominal, n_poses=24, size_px=(1280, 960),
                                f_px=1440.0, seed=seed)
    cli(["handeye", str(folder), "--out", str(folder.parent / "out"), "-q"])
    doc = read_json(folder.parent / "out" / "calibration.json")
    truth = read_json(folder / "truth.json")
    session = read_json(folder / "session.json")
    rng = np.random.default_rng(seed)
    print(f"arm camera, seed {seed}: {len(doc['cameras'][0]['images'])} photos, corner RMS "
          f"{doc['cameras'][0]['corner_rms_px']:.3f} px, photo-level scatter "
          f"{json.dumps({k: round(v, 4) for k, v in doc['pose_rms'].items()})}")
    v = doc["verdict"]
    print(f"  verdict {v['status']}: residual over floor {v['residual_over_floor']:.2f}, "
          f"expected target error {v['expected_target_error_mm']:.4f} mm (95 %)"
          + (f"; {'; '.join(v['reasons'])}" if v["reasons"] else ""))
    for name, z in (("plane", 0.0), ("+50 mm", 50.0)):
        err, ratio = _arm_locate(doc, truth, session, z, rng)
        e = np.hypot(*err.T)
        print(f"  {name:<10}  RMS {np.sqrt(np.mean(e**2)):.4f}  max {e.max():.4f}  "
              f"ratio {np.sqrt(np.mean(ratio**2)):.2f}")
    X, Xf = np.array(truth["T_flange_camera"]), np.array(doc["cameras"][0]["T_flange_camera"])
    sd = doc["cameras"][0]["T_flange_camera_std"]["translation_mm"]
    print("  T_flange_camera translation error (mm) / std: " + ", ".join(
        f"{a:+.4f}/{b:.4f}" for a, b in zip(Xf[:3, 3] - X[:3, 3], sd)))
    print("  kinematics: arm camera - pen method (combined std), and each against the truth")
    for k, lab in (("L1_mm", "L1"), ("L2_mm", "L2"), ("joint_zero_deg", "z"), ("base_mm", "base")):
        a, b = np.atleast_1d(doc["params"][k]), np.atleast_1d(pen["params"][k])
        sa, sb = np.atleast_1d(doc["std"][k]), np.atleast_1d(pen["std"][k])
        t = np.atleast_1d(truth_params[k])
        for i in range(len(a)):
            comb = np.hypot(sa[i], sb[i])
            print(f"    {lab}{i + 1 if len(a) > 1 else '':<3} {a[i] - b[i]:+.5f} ({comb:.5f}, "
                  f"{(a[i] - b[i]) / comb:+.2f} std)   camera-truth {a[i] - t[i]:+.5f} "
                  f"+- {sa[i]:.5f}   pen-truth {b[i] - t[i]:+.5f} +- {sb[i]:.5f}")


def poses_needed(target_mm: float = 0.02) -> None:
    import sys

    sys.path.insert(0, str(ROOT / "tests" / "camera"))
    import test_arm as world_views  # the tests' projected-corner world

    from vision_cal.camera.arm import fit_arm_camera
    from vision_cal.model.kinematics import jacobian

    print("arm camera: predicted flange std (per axis, RMS over the sheet) vs poses")
    grid = np.array([[a, b] for a in np.linspace(-60, 60, 7) for b in np.linspace(-140, 140, 8)
                     if abs(b) > 20])
    found = None
    for n in (6, 8, 12, 16, 24, 32):
        vals = []
        for k in range(5):
            rng = np.random.default_rng(1000 + 7 * n + k)
            X = world_views.world.T_flange_camera_true(rng)
            views = world_views._views(world_views._plan(n, rng), X, rng)
            fit = fit_arm_camera(views, world_views.K, None, world_views.NOMINAL)
            J = jacobian(fit.params, grid)                    # (M, 2, 6) internal units
            C = fit.cov[:6, :6].copy()
            C[2:4, :] = np.radians(C[2:4, :])
            C[:, 2:4] = np.radians(C[:, 2:4])
            var = np.einsum("mip,pq,miq->m", J, C, J) / 2
            vals.append(np.sqrt(np.mean(var)))
        v = float(np.median(vals))
        print(f"  {n:3d} poses: {v:.4f} mm")
        if found is None and v < target_mm:
            found = n
    print(f"  poses needed for {target_mm} mm: {found}"
          + (" (the fewest the fit accepts: camera/arm.MIN_POSES)" if found == 6 else ""))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[77, 78])
    ap.add_argument("--out", default="/tmp/bench-camera")
    ap.add_argument("--arm", action="store_true", help="the arm camera only")
    a = ap.parse_args()
    out = Path(a.out)
    if a.arm:
        poses_needed()
        for seed in a.seeds:
            arm(seed, out)
        return
    print("still camera: pixel -> robot frame error (mm): RMS, max, RMS(err/std)")
    for seed in a.seeds:
        for declared in (True, False):
            r = still(seed, declared, out)
            head = (f"seed {seed} lens {'declared' if declared else 'undeclared'} "
                    f"({r['intrinsics']}, f {r['f_px']:.1f} vs true {r['f_true']:.1f} px, "
                    f"{r['n_photos']} photos, {r['seconds']:.0f} s)")
            print(head)
            for k in ("plane", "+50 mm", "val marks"):
                v = r.get(k)
                print(f"  {k:<10}" + ("  not located (focal length undetermined)" if v is None
                                      else f"  RMS {v[0]:.4f}  max {v[1]:.4f}  ratio {v[2]:.2f}"))
            v = r.get("plate +50")
            if v is not None:
                print(f"  plate +50   RMS {v['rms']:.4f}  max {v['max']:.4f} over {v['n']} "
                      f"corners (detection {v['detection_px']:.3f} px RMS); each plate's mean "
                      f"error {v['plate_mean_rms']:.4f} RMS")


if __name__ == "__main__":
    main()
