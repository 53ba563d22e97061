"""The arm camera's verdict against a declared lens (issue 29): synthetic corners (no
rendering) from the world's robot and camera mount, projected through a true lens with
distortion, detected with 0.1 px noise; the estimator given a declared lens that is right,
30 % off in f, or without its distortion, or no lens at all.

    PYTHONPATH=. python bench/arm_lens.py [--seeds 3] [--tilt 2.5]
"""

from __future__ import annotations

import argparse

import cv2
import numpy as np

from vision_cal.camera.arm import ArmView, check_declared_lens, estimate_lens, fit_arm_camera
from vision_cal.actions.arm_camera import undetermined_reasons
from vision_cal.estimate.verdict import judge_camera_poses
from vision_cal.model.kinematics import ScaraParams
from vision_cal.world import arm_camera as world
from vision_cal.world.sheet import make_sheet
from vision_cal.world.truth_model import TrueRobot


SIZE = (1280, 960)
F = 1100.0
K = np.array([[F, 0, 639.5], [0, F, 479.5], [0, 0, 1]])
DIST = np.array([-0.045, 0.0, 0.0, 0.0, 0.0])
TRUTH = TrueRobot(344.05, 259.87, (-2.57, -8.13), (-424.26, -230.35))
NOMINAL = ScaraParams(350.0, 260.0, 0.0, 0.0, -410.0, -240.0)


def field():
    return make_sheet(size_mm=(594.0, 420.0), bottom_left_mm=(-297.0, -210.0),
                      dictionary="DICT_5X5_250", marker_mm=18.0, grid=(14, 10), margin_mm=12.0)


def plan(n, rng, truth=TRUTH):
    out = []
    while len(out) < n:
        q = np.array([rng.uniform(-60, 60), rng.uniform(-150, 150)])
        xy = truth.pen_mm(q[None])[0]
        if abs(xy[0]) < 200 and abs(xy[1]) < 130 and abs(q[1]) > 20:
            out.append((q, rng.uniform(-170, 170)))
    return out


def views(plan_, X, rng, *, K=K, dist=DIST, noise_px=0.1, repeatability_mm=0.01, truth=TRUTH):
    corners = np.concatenate([m.corners_mm for m in field().markers])
    q = np.array([p[0] for p in plan_])
    j4 = np.array([p[1] for p in plan_])
    T_sf = world.T_sheet_flange(truth, q, j4)
    T_sf[:, :2, 3] += rng.normal(0, repeatability_mm, (len(q), 2))
    out = []
    for i, T in enumerate(np.linalg.inv(T_sf @ X)):
        obj = np.column_stack([corners, np.zeros(len(corners))])
        pc = obj @ T[:3, :3].T + T[:3, 3]
        uv, _ = cv2.projectPoints(obj.reshape(-1, 1, 3), cv2.Rodrigues(T[:3, :3])[0],
                                  T[:3, 3], K, dist)
        uv = uv.reshape(-1, 2)
        inside = ((uv[:, 0] > 5) & (uv[:, 0] < SIZE[0] - 6) & (uv[:, 1] > 5)
                  & (uv[:, 1] < SIZE[1] - 6) & (pc[:, 2] > 0))
        inside = inside.reshape(-1, 4).all(axis=1).repeat(4)
        out.append(ArmView(f"p{i}", q[i], j4[i], corners[inside],
                           uv[inside] + rng.normal(0, noise_px, (inside.sum(), 2))))
    return out


def run(case, seed, tilt, n=24):
    rng = np.random.default_rng(seed)
    X = world.T_flange_camera_true(rng, height_mm=(190.0, 210.0), tilt_deg=(tilt, tilt))
    vs = views(plan(n, rng), X, rng)
    if case == "right":
        Kd, dd = K, DIST
    elif case == "f+30%":
        Kd, dd = K.copy(), DIST
        Kd[0, 0] = Kd[1, 1] = 1.3 * F
    elif case == "no dist":
        Kd, dd = K, np.zeros(5)
    else:
        lens = estimate_lens(vs, SIZE)
        Kd, dd = lens.K, lens.dist
    chk = check_declared_lens(vs, SIZE, Kd, dd) if case != "none" else None
    extra = list(chk.reasons) if chk else []
    if chk:
        print(f"   lens check: f views {chk.f_views_px:.1f} +- {chk.f_std_px:.2f} "
              f"({chk.f_sigmas:.1f} std), dist diff {chk.dist_px:+.3f} +- {chk.dist_std_px:.3f}"
              f" px, corner sigma {chk.corner_sigma_px:.3f} px")
    fit = fit_arm_camera(vs, Kd, dd, NOMINAL,
                         corner_sigma_px=chk.corner_sigma_px if chk else None,
                         lens_cov=lens.cov if case == "none" else None)
    v = judge_camera_poses(fit.flange_residual_mm, fit.flange_sigma_mm, fit.flange_heldout_mm,
                           n_params=fit.n_params_xy, repeatability_mm=0.01,
                           reasons=undetermined_reasons(fit, "flange") + extra)
    z = fit.T_flange_camera[2, 3]
    zs = float(fit.std[11])      # an estimated lens's f std is in it (as handeye's)
    print(f"{case:8s} seed {seed}: {v.status:12s} floor x{v.residual_over_floor:.2f} "
          f"height {z:.3f} +- {zs:.4f} (truth {X[2, 3]:.3f}, {abs(z - X[2, 3]) / zs:.0f} std) "
          f"corners {fit.corner_sigma_px:.3f} px | {'; '.join(v.reasons)[:120]}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--tilt", type=float, default=2.5)
    a = ap.parse_args()
    for case in ("right", "f+30%", "no dist", "none"):
        for s in range(a.seeds):
            run(case, 100 + s, a.tilt)
