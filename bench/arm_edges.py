"""Why a world with nothing missing read 1.4x its floor (issue 29): the arm camera's marker
corners were lines fitted to the border edges in the raw photo, where a lens with k1
-0.045 curves them. Synthetic detector: each marker's four sides sampled as edge points
through the true lens (0.02 px noise per point), corners from straight-line fits in raw
pixels ("raw", as before) or in the declared lens's ideal pixels ("lens", now); the
declared lens is the true one, the robot has nothing hidden.

    PYTHONPATH=. python bench/arm_edges.py [--seeds 4] [--noise 0.02]
"""

from __future__ import annotations

import argparse

import cv2
import numpy as np

from vision_cal.camera.arm import ArmView, check_declared_lens, fit_arm_camera, lens_corners
from vision_cal.estimate.verdict import judge_camera_poses
from vision_cal.measure.types import ImageDetections
from vision_cal.model.kinematics import ScaraParams
from vision_cal.world import arm_camera as world
from vision_cal.world.sheet import make_sheet
from vision_cal.world.truth_model import TrueRobot

SIZE = (1280, 960)
K = np.array([[1100.0, 0, 639.5], [0, 1100.0, 479.5], [0, 0, 1]])
DIST = np.array([-0.045, 0.0, 0.0, 0.0, 0.0])
TRUTH = TrueRobot(344.05, 259.87, (-2.57, -8.13), (-424.26, -230.35))
NOMINAL = ScaraParams(350.0, 260.0, 0.0, 0.0, -410.0, -240.0)


def markers():
    s = make_sheet(size_mm=(594.0, 420.0), bottom_left_mm=(-297.0, -210.0),
                   dictionary="DICT_5X5_250", marker_mm=18.0, grid=(14, 10), margin_mm=12.0)
    return np.array([m.corners_mm for m in s.markers])          # (M, 4, 2)


def plan(n, rng):
    out = []
    while len(out) < n:
        q = np.array([rng.uniform(-60, 60), rng.uniform(-150, 150)])
        xy = TRUTH.pen_mm(q[None])[0]
        if abs(xy[0]) < 200 and abs(xy[1]) < 130 and abs(q[1]) > 20:
            out.append((q, rng.uniform(-170, 170)))
    return out


def views(seed, noise, n=24):
    rng = np.random.default_rng(seed)
    X = world.T_flange_camera_true(rng, height_mm=(200.0, 210.0), tilt_deg=(2.5, 2.5))
    pl = plan(n, rng)
    q = np.array([p[0] for p in pl])
    j4 = np.array([p[1] for p in pl])
    T_sf = world.T_sheet_flange(TRUTH, q, j4)
    T_sf[:, :2, 3] += rng.normal(0, 0.01, (len(q), 2))
    mk = markers()
    t = np.linspace(0.15, 0.85, 16)
    raw, lens = [], []
    for i, T in enumerate(np.linalg.inv(T_sf @ X)):
        rv = cv2.Rodrigues(T[:3, :3])[0]
        sides = np.stack([mk[:, k, None] + t[None, :, None] * (mk[:, (k + 1) % 4, None]
                                                               - mk[:, k, None])
                          for k in range(4)], axis=1)            # (M, 4, n, 2) sheet mm
        pts = np.concatenate([sides.reshape(-1, 2), mk.reshape(-1, 2)])
        obj = np.column_stack([pts, np.zeros(len(pts))])
        uv = cv2.projectPoints(obj.reshape(-1, 1, 3), rv, T[:3, 3], K, DIST)[0].reshape(-1, 2)
        e = uv[:sides.size // 2].reshape(sides.shape) + rng.normal(0, noise, sides.shape)
        c = uv[sides.size // 2:].reshape(mk.shape)
        ok = np.all((c[..., 0] > 5) & (c[..., 0] < SIZE[0] - 6) & (c[..., 1] > 5)
                    & (c[..., 1] < SIZE[1] - 6), axis=1)
        det = ImageDetections(f"p{i}", "ok", corners_px=c[ok] + 0.3, edges_px=e[ok])
        cr, cl = lens_corners(det), lens_corners(det, K, DIST)
        raw.append(ArmView(f"p{i}", q[i], j4[i], mk[ok].reshape(-1, 2), cr.reshape(-1, 2)))
        lens.append(ArmView(f"p{i}", q[i], j4[i], mk[ok].reshape(-1, 2), cl.reshape(-1, 2)))
    return raw, lens


def judge(vs):
    chk = check_declared_lens(vs, SIZE, K, DIST)
    fit = fit_arm_camera(vs, K, DIST, NOMINAL, corner_sigma_px=chk.corner_sigma_px)
    v = judge_camera_poses(fit.flange_residual_mm, fit.flange_sigma_mm, fit.flange_heldout_mm,
                           n_params=fit.n_params_xy, repeatability_mm=0.01,
                           heldout_inflate=fit.flange_heldout_inflate,
                           reasons=list(chk.reasons))
    return v, chk


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--noise", type=float, default=0.02)
    a = ap.parse_args()
    for s in range(a.seeds):
        raw, lens = views(300 + s, a.noise)
        for name, vs in (("raw", raw), ("lens", lens)):
            v, chk = judge(vs)
            f = v.floor
            print(f"seed {300 + s} {name:4s}: {v.status:12s} residual/floor "
                  f"{f['residual_over_floor']:.2f} (p = {f['p_value']:.2g}), corners "
                  f"{chk.corner_sigma_px:.3f} px {'; '.join(v.reasons)[:90]}")
