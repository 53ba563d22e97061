"""Hand-eye from pose pairs (issue 32): the solver against the world's truth over seeds, and
against OpenCV's ``calibrateRobotWorldHandEye`` on the same pairs.

For each seed the world (render/pose_pairs.py: the true SM5, a camera drawn on its flange
or standing over the work area, a board) gives N pose pairs with either 0.1 px of corner
noise solved by PnP (``px``) or 1 mm / 0.5 deg on the board's pose (``pose``). Printed per
case: the RMS over seeds of error / reported std for each of X's six parameters (1 when
the std is right), the share of parameters within 2 std (95 % when right), the pairs left
out of clean data (false alarms), the median time, and for OpenCV (when the installed cv2
has it: the pip build of OpenCV 5.0 does not) its error and its time on the same pairs.

    python bench/handeye_pairs.py --seeds 30 --pairs 20
    python bench/handeye_pairs.py --opencv-python /tmp/cv4/bin/python   # an OpenCV 4 elsewhere

``--opencv-python``: a Python whose cv2 has ``calibrateRobotWorldHandEye``; the pairs are
handed to it through a temporary .npz and its X read back (the project's venv keeps its
OpenCV 5).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
import textwrap
import time
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from vision_cal.camera.pose_pairs import PosePair, fit_pose_pairs
from vision_cal.render.pose_pairs import simulate_pairs
from vision_cal.render.truth_model import TrueRobot

TRUTH = TrueRobot(344.05, 259.87, (-2.57, -8.13), (-424.26, -230.35))
NOISE = {"px": {"noise_px": 0.1}, "pose": {"noise_px": None, "noise_mm": 1.0, "noise_deg": 0.5}}

#: run in the other Python: OpenCV's robot-world hand-eye (eye-in-hand: base->gripper and
#: world->camera; X = gripper->camera ... in its naming: R_base2gripper, R_world2cam give
#: R_base2world, R_gripper2cam)
_OPENCV = textwrap.dedent("""
    import sys, time, numpy as np, cv2
    d = np.load(sys.argv[1])
    A, B = d["A"], d["B"]          # T_robot_flange, T_camera_target (mm)
    # OpenCV: world = target, base = robot, gripper = flange:
    # R_world2cam, t_world2cam = T_camera_target; R_base2gripper = inv(T_robot_flange)
    Ai = np.linalg.inv(A)
    out = {}
    for name, m in (("SHAH", cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH),
                    ("LI", cv2.CALIB_ROBOT_WORLD_HAND_EYE_LI)):
        t0 = time.perf_counter()
        R_b2w, t_b2w, R_g2c, t_g2c = cv2.calibrateRobotWorldHandEye(
            [b[:3, :3] for b in B], [b[:3, 3:] for b in B],
            [a[:3, :3] for a in Ai], [a[:3, 3:] for a in Ai], method=m)
        dt = time.perf_counter() - t0
        T = np.eye(4); T[:3, :3] = R_g2c; T[:3, 3] = t_g2c.ravel()
        out[name] = (np.linalg.inv(T), dt)   # T_flange_camera = inv(T_camera_flange)
    np.savez(sys.argv[2], **{k + "_X": v[0] for k, v in out.items()},
             **{k + "_t": v[1] for k, v in out.items()})
""")


def _err(X, X_true) -> np.ndarray:
    dr = np.degrees(Rotation.from_matrix(X[:3, :3] @ X_true[:3, :3].T).as_rotvec())
    return np.concatenate([dr, X[:3, 3] - X_true[:3, 3]])


def _opencv_here(A, B):
    """OpenCV in this Python, when its cv2 has the function (None otherwise)."""
    if not hasattr(cv2, "calibrateRobotWorldHandEye"):
        return None
    Ai = np.linalg.inv(A)
    t0 = time.perf_counter()
    _, _, R, t = cv2.calibrateRobotWorldHandEye(
        [b[:3, :3] for b in B], [b[:3, 3:] for b in B], [a[:3, :3] for a in Ai],
        [a[:3, 3:] for a in Ai], method=cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t.ravel()
    return {"SHAH": (np.linalg.inv(T), time.perf_counter() - t0)}


def _opencv_there(python, A, B):
    with tempfile.TemporaryDirectory() as d:
        src, out, script = Path(d) / "in.npz", Path(d) / "out.npz", Path(d) / "cv.py"
        np.savez(src, A=A, B=B)
        script.write_text(_OPENCV)
        r = subprocess.run([python, str(script), str(src), str(out)], capture_output=True,
                           text=True, timeout=120)
        if r.returncode:
            return {"error": r.stderr.strip().splitlines()[-1] if r.stderr else "failed"}
        z = np.load(out)
        return {k: (z[k + "_X"], float(z[k + "_t"])) for k in ("SHAH", "LI")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--pairs", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=5000)
    ap.add_argument("--opencv-python", default=None,
                    help="a Python whose cv2 has calibrateRobotWorldHandEye (OpenCV 4)")
    ap.add_argument("--json", default=None, help="also write the figures here")
    a = ap.parse_args()
    print(f"installed cv2 {cv2.__version__}: calibrateRobotWorldHandEye "
          f"{'present' if hasattr(cv2, 'calibrateRobotWorldHandEye') else 'absent'}")
    figures = {}
    for mount in ("arm", "fixed"):
        for noise, kw in NOISE.items():
            zs, times, falses, unseen, ocv = [], [], 0, 0, {}
            for seed in range(a.first_seed, a.first_seed + a.seeds):
                w = simulate_pairs(TRUTH, a.pairs, seed=seed, mount=mount, **kw)
                pairs = [PosePair(str(i), p, q) for i, (p, q) in enumerate(zip(w["A"], w["B"]))]
                t0 = time.perf_counter()
                fit = fit_pose_pairs(pairs, mount, z_mm=float(w["Y"][2, 3]))
                times.append(time.perf_counter() - t0)
                free = fit_pose_pairs(pairs, mount)     # without the height: flagged?
                unseen += int(any(d["label"] == "X_z_mm" for d in free.not_identifiable))
                falses += len(fit.outliers)
                zs.append(_err(fit.X, w["X"]) / np.sqrt(np.diag(fit.cov))[:6])
                if mount == "arm":
                    res = (_opencv_there(a.opencv_python, w["A"], w["B"]) if a.opencv_python
                           else _opencv_here(w["A"], w["B"]))
                    for k, v in (res or {}).items():
                        if k == "error":
                            ocv.setdefault("error", v)
                            continue
                        e = _err(v[0], w["X"])
                        ocv.setdefault(k, []).append((np.linalg.norm(e[3:]),
                                                      np.linalg.norm(e[:3]), v[1]))
            zs = np.array(zs)
            row = {"rms_error_over_std": np.sqrt(np.mean(zs**2, axis=0)).round(2).tolist(),
                   "within_2_std": float(np.mean(np.abs(zs) < 2.0)),
                   "false_outliers": falses, "height_flagged": f"{unseen}/{a.seeds}",
                   "median_time_s": float(np.median(times))}
            print(f"{mount:5s} {noise:4s}: error/std RMS (rot x y z, t x y z) "
                  f"{row['rms_error_over_std']}, within 2 std {row['within_2_std']:.1%}, "
                  f"pairs falsely left out {falses} in {a.seeds} sets, height flagged "
                  f"{row['height_flagged']}, {row['median_time_s'] * 1e3:.0f} ms")
            for k, v in ocv.items():
                if k == "error":
                    print(f"        OpenCV: {v}")
                    row["opencv_error"] = v
                    continue
                v = np.array(v)
                row[f"opencv_{k}"] = {"median_t_err_mm": float(np.median(v[:, 0])),
                                      "median_r_err_deg": float(np.median(v[:, 1])),
                                      "median_time_s": float(np.median(v[:, 2]))}
                print(f"        OpenCV {k}: |t error| median {np.median(v[:, 0]):.3f} mm, "
                      f"|rotation error| {np.median(v[:, 1]):.3f} deg, "
                      f"{np.median(v[:, 2]) * 1e3:.2f} ms")
            figures[f"{mount}/{noise}"] = row
    if a.json:
        Path(a.json).write_text(json.dumps(figures, indent=1))


if __name__ == "__main__":
    main()
