"""The arm camera's stated std against the truth (issue 37): ``locate`` on the sheet and
50 mm above it, with the lens declared and undeclared, over rendered worlds.

Each seed renders the world's camera on the true robot (world/arm_camera.py: 24 poses,
1280 x 960 px, 0.01 mm repeatability per photo, a mount drawn 150-250 mm above the flange
and tilted up to 4 deg; odd seeds add a lens with k1 -0.045) and calibrates the same photos
twice: with session.json's lens (``declared``) and without it (``undeclared``: the lens
estimated from the views). For each photo, 20 true points within 40 mm of the view's
centre, on the sheet (z 0) and 50 mm above it, are projected by the photo's true camera
(lens included) and located through the fitted robot and ``T_flange_camera`` at the
commanded joints (``camera/arm.camera_for``, as ``vision-cal locate --photo``). Printed per
seed and pooled: the RMS error, RMS(error / std) per axis (1 when the std is right), the
share of points inside their 95 % ellipse (2-D, chi-square 2 dof), what locate said when it
refused; and the verdicts (the rate of "ready" where nothing is missing).

    PYOPENGL_PLATFORM=egl python bench/arm_locate.py --seeds 20 --first-seed 3710 \
        [--work /tmp/arm_locate]   # renders are kept there and reused
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import time
from collections import Counter
from pathlib import Path

import cv2
import numpy as np
from scipy import stats

from vision_cal.camera.arm import camera_for
from vision_cal.camera.fixed import locate
from vision_cal.dataset.io import atomic_write_json, read_json
from vision_cal.errors import VisionCalError
from vision_cal.world.arm_camera import render_arm_dataset
from vision_cal.actions.arm_camera import calibrate_arm_camera

TRUTH = {"L1_mm": 344.05, "L2_mm": 259.87, "joint_zero_deg": [-2.57, -8.13],
         "base_mm": [-424.26, -230.35]}
NOMINAL = {"L1_mm": 350.0, "L2_mm": 260.0, "joint_zero_deg": [0.0, 0.0],
           "base_mm": [-410.0, -240.0]}
#: the 95 % ellipse of a 2-D normal
CHI2_95_2 = float(stats.chi2.ppf(0.95, 2))
HEIGHTS = (0.0, 50.0)


def _T_robot_sheet(params: dict) -> np.ndarray:
    """The contract's robot frame in the sheet: p_S = base + Rot(z1) p_R; returns T_R_S."""
    a = np.radians(params["joint_zero_deg"][0])
    T = np.eye(4)
    T[:2, :2] = [[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]
    T[:2, 3] = params["base_mm"]
    return np.linalg.inv(T)


def located(doc: dict, truth: dict, z_mm: float, rng) -> dict:
    """Per photo, 20 true points at height ``z_mm`` located through the calibration:
    errors (N, 2) mm, their std (N, 2), and the refusals (reason: count)."""
    T_rs = _T_robot_sheet(truth["params"])
    K = np.array(truth["camera"]["K"])
    dist = np.array(truth["camera"]["dist"], float)
    w, h = doc["cameras"][0]["size_px"]
    errs, sds, refused = [], [], Counter()
    for pose in doc["poses"]:
        T_cs = np.array(truth["camera"]["T_cam_sheet"][pose["image"]])
        centre = np.linalg.inv(T_cs)[:2, 3]
        p_s = np.column_stack([centre + rng.uniform(-40, 40, (20, 2)), np.full(20, z_mm)])
        uv = cv2.projectPoints(p_s.reshape(-1, 1, 3), cv2.Rodrigues(T_cs[:3, :3])[0],
                               T_cs[:3, 3], K, dist)[0].reshape(-1, 2)
        ok = (uv[:, 0] > 0) & (uv[:, 0] < w - 1) & (uv[:, 1] > 0) & (uv[:, 1] < h - 1)
        try:
            got = locate(camera_for(doc, 0, photo=pose["image"]), uv[ok], z_mm)
        except VisionCalError as e:
            refused[e.reason[:90]] += 1
            continue
        true_r = p_s[ok] @ T_rs[:3, :3].T + T_rs[:3, 3]
        errs.append(np.array([g.robot_mm[:2] for g in got]) - true_r[:, :2])
        sds.append(np.array([g.robot_std_mm[:2] for g in got]))
    if not errs:
        return {"errors": np.zeros((0, 2)), "std": np.zeros((0, 2)), "refused": refused}
    return {"errors": np.concatenate(errs), "std": np.concatenate(sds), "refused": refused}


def summary(errors: np.ndarray, std: np.ndarray) -> dict:
    """RMS error (mm, 2-D), RMS of error / std per axis, share inside the 95 % ellipse
    (each point's axes taken independent)."""
    if not len(errors):
        return {"n": 0}
    z = errors / np.maximum(std, 1e-12)
    return {"n": int(len(errors)), "rms_mm": float(np.sqrt(np.mean(np.sum(errors**2, axis=1)))),
            "max_mm": float(np.max(np.hypot(*errors.T))),
            "median_std_mm": float(np.median(np.hypot(*std.T))),
            "ratio": float(np.sqrt(np.mean(z**2))),
            "inside_95": float(np.mean(np.sum(z**2, axis=1) < CHI2_95_2))}


def world(seed: int, work: Path) -> Path:
    """The rendered photos of ``seed`` (kept in ``work``)."""
    folder = work / f"seed-{seed}" / "data"
    if not (folder / "truth.json").exists():
        shutil.rmtree(folder, ignore_errors=True)
        dist = [-0.045, 0.0, 0.0, 0.0, 0.0] if seed % 2 else None
        render_arm_dataset(folder, truth=TRUTH, nominal=NOMINAL, n_poses=24,
                           size_px=(1280, 960), f_px=1440.0, seed=seed, dist=dist)
    return folder


def calibrate(folder: Path, declared: bool) -> dict:
    """calibration.json of the photos, the lens declared or left out of session.json."""
    case = folder.parent / ("declared" if declared else "undeclared")
    case.mkdir(exist_ok=True)
    session = read_json(folder / "session.json")
    if not declared:
        session.pop("camera", None)
    for f in folder.iterdir():
        if f.suffix == ".png":
            if (case / f.name).is_symlink():
                (case / f.name).unlink()
            if not (case / f.name).exists():
                os.link(f, case / f.name)         # a hard link: photos stay inside the folder
    atomic_write_json(case / "session.json", session)
    return calibrate_arm_camera(case, cache_dir=folder.parent / f".cache-{case.name}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=3710)
    ap.add_argument("--work", default="/tmp/arm_locate")
    ap.add_argument("--json", default=None, help="also write the figures here")
    a = ap.parse_args()
    work = Path(a.work)
    work.mkdir(parents=True, exist_ok=True)
    pooled = {(c, z): ([], []) for c in ("declared", "undeclared") for z in HEIGHTS}
    verdicts = {c: Counter() for c in ("declared", "undeclared")}
    refusals = {c: Counter() for c in ("declared", "undeclared")}
    rows = []
    for seed in range(a.first_seed, a.first_seed + a.seeds):
        t0 = time.perf_counter()
        folder = world(seed, work)
        truth = read_json(folder / "truth.json")
        for case in ("declared", "undeclared"):
            doc = calibrate(folder, case == "declared")
            v = doc["verdict"]
            verdicts[case][v["status"]] += 1
            cam = doc["cameras"][0]
            line = (f"seed {seed} {case:10s} {v['status']:12s} x{v['residual_over_floor']:.2f} "
                    f"f {cam['K'][0][0]:.0f}" + (f" +- {cam['f_px_std']:.1f}"
                                                  if cam.get("f_px_std") else ""))
            row = {"seed": seed, "case": case, "status": v["status"],
                   "residual_over_floor": v["residual_over_floor"],
                   "reasons": v["reasons"]}
            rng = np.random.default_rng(seed)
            for z in HEIGHTS:
                got = located(doc, truth, z, rng)
                s = summary(got["errors"], got["std"])
                pooled[(case, z)][0].append(got["errors"])
                pooled[(case, z)][1].append(got["std"])
                refusals[case].update(got["refused"])
                row[f"z{z:g}"] = s
                line += (f" | z {z:+.0f}: " + (f"RMS {s['rms_mm']:.4f} std {s['median_std_mm']:.4f} "
                                               f"ratio {s['ratio']:.2f} in95 {s['inside_95']:.0%}"
                                               if s["n"] else "refused"))
            print(line + (f"  [{'; '.join(v['reasons'])[:160]}]" if v["reasons"] else ""),
                  flush=True)
            rows.append(row)
        print(f"  ({time.perf_counter() - t0:.0f} s)", flush=True)
    figures = {"rows": rows}
    print(f"\npooled over seeds {a.first_seed}-{a.first_seed + a.seeds - 1}:")
    for (case, z), (e, s) in pooled.items():
        e = np.concatenate(e) if e else np.zeros((0, 2))
        s = np.concatenate(s) if s else np.zeros((0, 2))
        sm = summary(e, s)
        figures[f"{case}/z{z:g}"] = sm
        print(f"  {case:10s} z {z:+3.0f} mm: " + (
            f"{sm['n']} points, RMS {sm['rms_mm']:.4f} mm, median std {sm['median_std_mm']:.4f}, "
            f"RMS(err/std) {sm['ratio']:.2f}, inside 95 % ellipse {sm['inside_95']:.1%}"
            if sm["n"] else "no points located"))
    for case in verdicts:
        print(f"  verdicts {case}: {dict(verdicts[case])}"
              + (f"; locate refused: {dict(refusals[case])}" if refusals[case] else ""))
        figures[f"verdicts/{case}"] = dict(verdicts[case])
    if a.json:
        Path(a.json).write_text(json.dumps(figures, indent=1))


if __name__ == "__main__":
    main()
