"""Hand-eye from pose pairs (issue 32): the solver against the world's truth over seeds, and
against OpenCV's ``calibrateRobotWorldHandEye`` on the same pairs.

For each seed the world (worlds/pose_pairs.py: the true SM5, a camera drawn on its flange
or standing over the work area, a board) gives N pose pairs with either 0.1 px of corner
noise solved by PnP (``px``) or 1 mm / 0.5 deg on the board's pose (``pose``). Printed per
case: the RMS over seeds of error / reported std for each of X's six parameters (1 when
the std is right), the share of parameters within 2 std (95 % when right), the pairs left
out of clean data (false alarms), the median time, and for OpenCV (when the installed cv2
has it: the pip build of OpenCV 5.0 does not) its error and its time on the same pairs.

    python bench/handeye_pairs.py --seeds 30 --pairs 20
    python bench/handeye_pairs.py --opencv-python /tmp/cv4/bin/python   # an OpenCV 4 elsewhere
    python bench/handeye_pairs.py --probes --seeds 20     # issue 40's broken files
    python bench/handeye_pairs.py --speed 10000            # issue 41: the cost per pair

``--probes``: on each seed's clean pairs, the cases issue 40 names (an arm parked while only
joint 4 turns, the target's rotation transposed under a tilted camera, pairs in cm and in
inches, 8 and 11 of 20 boards misdetected by 5-19 mm, 20 poses written 100 times, a
flange in metres with the board in mm, either transform inverted, a fixed camera read as
on the arm, a rotation vector in degrees, a height of 1e9 mm): the verdict of each and
whether its first reason names the cause; none may be "ready" (the repeats excepted: they
are counted once, and then "ready" is right). ``--speed N``: ``handeye --poses``' fit of N
distinct pairs against a plain least squares of the same 11 parameters from the same
closed form (one unweighted ``scipy.optimize.least_squares``: what a user would write),
in one process; the fit's cost per pair at 1,000 and N pairs (linear: the same).

``--opencv-python``: a Python whose cv2 has ``calibrateRobotWorldHandEye``; the pairs are
handed to it through a temporary .npz and its X read back (the project's venv keeps its
OpenCV 5). ``--photos``: also the photo-based ``handeye`` (camera/arm.fit_arm_camera on the
views' corners, 0.1 px) against pose pairs from the same views.

Figures (2026-11-26, ``--seeds 20 --pairs 20 --photos --opencv-python`` an OpenCV 4.14.0
venv; seeds 5000-5019): error/std RMS per parameter 0.67-1.15 in all four cases (arm/fixed x
px/pose), 95.0-97.5 % of parameters within 2 std, no pair falsely left out in 80 sets, the
height flagged in 80/80 without ``--z-mm``, 135-365 ms a fit (pure Python loops); OpenCV
4.14 ``calibrateRobotWorldHandEye`` (SHAH and LI) failed on 40/40 SCARA sets ("Rotation
normalization issue: determinant(R) is null": every motion turns about one axis). Photos
vs pairs on the same robot and views (10 seeds, 16 poses): photo-based 0.032 mm / 0.009
deg median error; pairs with an exact controller 0.039 mm / 0.0085 deg; pairs with the
nominal controller (links 6 mm off) 3.2 mm / 1.28 deg: pose pairs are only as good as the
controller's kinematics.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from vision_cal.actions.handeye import pairs_document
from vision_cal.camera.pose_pairs import PosePair, fit_pose_pairs
from vision_cal.world.arm_camera import T_flange_camera_true
from vision_cal.world.truth_model import TrueRobot

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))   # the test and bench worlds (worlds/, not installed)

from worlds.pose_pairs import simulate_many_pairs, simulate_pairs  # noqa: E402

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
    for name in ("SHAH", "LI"):
        t0 = time.perf_counter()
        try:
            R_b2w, t_b2w, R_g2c, t_g2c = cv2.calibrateRobotWorldHandEye(
                [b[:3, :3] for b in B], [b[:3, 3:] for b in B],
                [a[:3, :3] for a in Ai], [a[:3, 3:] for a in Ai],
                method=getattr(cv2, "CALIB_ROBOT_WORLD_HAND_EYE_" + name))
        except cv2.error as e:
            out[name + "_error"] = np.array(str(e).strip().splitlines()[-1][:160])
            continue
        dt = time.perf_counter() - t0
        T = np.eye(4); T[:3, :3] = R_g2c; T[:3, 3] = t_g2c.ravel()
        W = np.eye(4); W[:3, :3] = R_b2w; W[:3, 3] = t_b2w.ravel()
        out[name + "_X"] = np.linalg.inv(T)   # T_flange_camera = inv(T_camera_flange)
        out[name + "_Y"] = np.linalg.inv(W)   # T_robot_target = inv(T_world_base)
        out[name + "_t"] = np.array(dt)
    np.savez(sys.argv[2], **out)
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
    try:
        Rw, tw, R, t = cv2.calibrateRobotWorldHandEye(
            [b[:3, :3] for b in B], [b[:3, 3:] for b in B], [a[:3, :3] for a in Ai],
            [a[:3, 3:] for a in Ai], method=cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH)
    except cv2.error as e:
        return {"SHAH": str(e).strip().splitlines()[-1][:160]}
    T, W = np.eye(4), np.eye(4)
    T[:3, :3], T[:3, 3] = R, t.ravel()
    W[:3, :3], W[:3, 3] = Rw, tw.ravel()
    return {"SHAH": (np.linalg.inv(T), time.perf_counter() - t0, np.linalg.inv(W))}


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
        res = {}
        for k in ("SHAH", "LI"):
            if k + "_error" in z:
                res[k] = str(z[k + "_error"])
            else:
                res[k] = (z[k + "_X"], float(z[k + "_t"]), z[k + "_Y"])
        return res


def _pair_rms(A, B, X, Y) -> float:
    """RMS over the pairs of where each puts the target against Y (mm, 3-D)."""
    P = A @ X @ B
    return float(np.sqrt(np.mean(np.sum((P[:, :3, 3] - Y[:3, 3]) ** 2, axis=1))))


def photo_comparison(seeds, n_poses: int = 16) -> None:
    """The same simulated robot and camera, photo-based ``handeye`` (the robot calibrated
    with the camera from marker corners, 0.1 px) against pose pairs from the same views
    (board pose by PnP of the same corners) with the flange poses a controller reports:
    from its nominal model (mm off), or exact (a calibrated robot)."""
    # imported here: the photo-based comparison only
    from tests.camera.test_arm import K, NOMINAL, TRUTH as T_ARM, _plan, _views
    from vision_cal.camera.arm import camera_pose, fit_arm_camera
    from vision_cal.model.kinematics import ScaraParams
    from vision_cal.world import arm_camera as world

    def controller(params: ScaraParams, q, j4):
        """The flange a controller with ``params`` reports in its own frame (base at its
        origin, joint zeros its own: z1, z2 taken as the controller's zero offsets)."""
        a1 = np.radians(q[0] + params.z1_deg)
        a12 = a1 + np.radians(q[1] + params.z2_deg)
        T = np.eye(4)
        c, s_ = np.cos(a12 + np.radians(j4)), np.sin(a12 + np.radians(j4))
        T[:2, :2] = [[c, -s_], [s_, c]]
        T[:2, 3] = [params.L1_mm * np.cos(a1) + params.L2_mm * np.cos(a12),
                    params.L1_mm * np.sin(a1) + params.L2_mm * np.sin(a12)]
        return T

    true_ctrl = ScaraParams(T_ARM.L1_mm, T_ARM.L2_mm, T_ARM.zero_deg[0], T_ARM.zero_deg[1],
                            0.0, 0.0)
    rows = {"photos": [], "pairs, nominal controller": [], "pairs, exact controller": []}
    for seed in seeds:
        rng = np.random.default_rng(seed)
        X = world.T_flange_camera_true(rng)
        plan = _plan(n_poses, rng)
        views = _views(plan, X, rng)
        t0 = time.perf_counter()
        fit = fit_arm_camera(views, K, np.zeros(5), NOMINAL)
        rows["photos"].append((_err(fit.T_flange_camera, X), time.perf_counter() - t0))
        B = [np.linalg.inv(camera_pose(v, K, np.zeros(5))) for v in views]   # T_cam_sheet
        for name, params in (("pairs, nominal controller", NOMINAL),
                             ("pairs, exact controller", true_ctrl)):
            pairs = [PosePair(v.file, controller(params, v.q_deg, v.j4_deg), b)
                     for v, b in zip(views, B)]
            t0 = time.perf_counter()
            pf = fit_pose_pairs(pairs, "arm", z_mm=0.0)
            rows[name].append((_err(pf.X, X), time.perf_counter() - t0))
    print(f"photo-based handeye vs pose pairs, same robot and views ({len(seeds)} seeds, "
          f"{n_poses} poses, 0.1 px): median |error| of T_flange_camera")
    for name, v in rows.items():
        e = np.array([r[0] for r in v])
        print(f"  {name:27s}: translation {np.median(np.linalg.norm(e[:, 3:], axis=1)):.3f} "
              f"mm (xy {np.median(np.linalg.norm(e[:, 3:5], axis=1)):.3f}), rotation "
              f"{np.median(np.linalg.norm(e[:, :3], axis=1)):.4f} deg, "
              f"{np.median([r[1] for r in v]) * 1e3:.0f} ms")


def _broken(seed: int) -> dict:
    """Issue 40's cases on the world of ``seed``: name -> (pairs, mount, z_mm, the words
    the first reason must hold, truth X)."""
    w = simulate_many_pairs(TRUTH, 20, seed=seed)
    X = w["X"]
    rng = np.random.default_rng(seed)
    mk = (lambda A, B, rv=None, yw=None: [
        PosePair(f"p{i:02d}", a, b, None if yw is None else float(yw[i]),
                 None if rv is None else tuple(rv[i])) for i, (a, b) in enumerate(zip(A, B))])
    rv = Rotation.from_matrix(w["B"][:, :3, :3]).as_rotvec()
    cases = {"clean": (mk(w["A"], w["B"]), "arm", 0.0, "", X)}
    q = w["q"][np.argmin(np.linalg.norm(w["A"][:, :2, 3] - w["Y"][:2, 3], axis=1))]
    try:
        wp = simulate_pairs(TRUTH, 16, seed=seed, mount="arm", X=X, reach_mm=150.0,
                            commands=[(q[0], q[1], j) for j in np.linspace(-170, 170, 80)])
        cases["parked, joint 4 turns"] = (mk(wp["A"], wp["B"]), "arm", 0.0, "one place", X)
    except ValueError:
        pass
    Xt = T_flange_camera_true(rng, tilt_deg=(15.0, 25.0))
    wt = simulate_many_pairs(TRUTH, 20, seed=seed + 1, X=Xt, reach_mm=80.0)
    Bt = wt["B"].copy()
    Bt[:, :3, :3] = np.transpose(Bt[:, :3, :3], (0, 2, 1))
    cases["target R transposed (tilted)"] = (mk(wt["A"], Bt), "arm", 0.0, "transposed", Xt)
    for unit, f in (("cm", 10.0), ("inches", 25.4)):
        A, B = w["A"].copy(), w["B"].copy()
        A[:, :3, 3] /= f
        B[:, :3, 3] /= f
        cases[f"pairs in {unit}"] = (mk(A, B), "arm", 0.0, "centimetres or inches", X)
    for n_bad in (8, 11):
        B = w["B"].copy()
        for i in rng.choice(20, n_bad, replace=False):
            d = rng.normal(size=3)
            B[i, :3, 3] += d / np.linalg.norm(d) * rng.uniform(5.0, 19.0)
        cases[f"{n_bad}/20 misdetected"] = (mk(w["A"], B), "arm", 0.0, "disagree", X)
    cases["20 poses x 100"] = (mk(np.tile(w["A"], (100, 1, 1)), np.tile(w["B"], (100, 1, 1))),
                               "arm", 0.0, "", X)
    A = w["A"].copy()
    A[:, :3, 3] /= 1000.0
    cases["flange m, board mm"] = (mk(A, w["B"]), "arm", 0.0, "metres", X)
    cases["flange inverted"] = (mk(np.linalg.inv(w["A"]), w["B"]), "arm", 0.0, "--mount fixed", X)
    cases["target inverted"] = (mk(w["A"], np.linalg.inv(w["B"])), "arm", 0.0, "inverted", X)
    Bd = w["B"].copy()
    Bd[:, :3, :3] = Rotation.from_rotvec(np.degrees(rv)).as_matrix()
    cases["rvec in degrees"] = (mk(w["A"], Bd, np.degrees(rv)), "arm", 0.0, "degrees", X)
    wf = simulate_pairs(TRUTH, 20, seed=seed, mount="fixed", noise_px=0.1)
    cases["fixed read as arm"] = (mk(wf["A"], wf["B"]), "arm", 0.0, "--mount fixed", wf["X"])
    cases["height 1e9 mm"] = (mk(w["A"], w["B"]), "arm", 1e9, "height", X)
    return cases


def probes(seeds) -> dict:
    """Issue 40's cases over ``seeds``: per case the verdicts and how often the first
    reason (or the refusal) names the cause."""
    table: dict = {}
    for seed in seeds:
        for name, (pairs, mount, z, words, X) in _broken(seed).items():
            fit = fit_pose_pairs(pairs, mount, z_mm=z)
            if not fit:
                status, first = "refused", fit.reason
            else:
                v = pairs_document(fit, source="bench", units="mm")["verdict"]
                status, first = v["status"], (v["reasons"] or [""])[0]
            row = table.setdefault(name, {"status": {}, "named": 0, "n": 0, "err_mm": []})
            row["status"][status] = row["status"].get(status, 0) + 1
            row["named"] += int(words in first)
            row["n"] += 1
            if fit:
                row["err_mm"].append(float(np.linalg.norm(fit.X[:3, 3] - X[:3, 3])))
    print(f"issue 40's cases over seeds {seeds[0]}-{seeds[-1]} (verdict counts; the first "
          "reason names the cause; median |t error| of X):")
    for name, row in table.items():
        err = f"{np.median(row['err_mm']):.3g} mm" if row["err_mm"] else "-"
        print(f"  {name:30s} {json.dumps(row['status']):45s} cause named {row['named']}/"
              f"{row['n']}  error {err}")
        row["err_mm"] = float(np.median(row["err_mm"])) if row["err_mm"] else None
    return table


def _plain(A, B, z):
    """What a user would write: one unweighted least squares of the 11 parameters (X's
    rotation vector and translation, Y's rotation vector and x, y) from the same closed
    form, each pair's target translation (mm) and rotation (deg) against Y's (no weights,
    no outliers, no checks)."""
    from scipy.optimize import least_squares

    from vision_cal.camera.pairs_geometry import closed_form, rotvec

    X0, Y0 = closed_form(A, B, z)

    def unpack(x):
        X, Y = np.eye(4), np.eye(4)
        X[:3, :3] = Rotation.from_rotvec(x[:3]).as_matrix() @ X0[:3, :3]
        X[:3, 3] = X0[:3, 3] + x[3:6]
        Y[:3, :3] = Rotation.from_rotvec(x[6:9]).as_matrix() @ Y0[:3, :3]
        Y[:3, 3] = [Y0[0, 3] + x[9], Y0[1, 3] + x[10], z]
        return X, Y

    def residual(x):
        X, Y = unpack(x)
        P = A @ X @ B
        return np.hstack([P[:, :3, 3] - Y[:3, 3],
                          np.degrees(rotvec(Y[:3, :3].T @ P[:, :3, :3]))]).ravel()

    return least_squares(residual, np.zeros(11), method="lm").x


def speed(n: int) -> dict:
    """The fit's cost at 1,000 and ``n`` distinct pairs against the plain least squares."""
    out = {}
    for m in sorted({1000, n}):
        w = simulate_many_pairs(TRUTH, m, seed=4141)
        pairs = [PosePair(str(i), a, b) for i, (a, b) in enumerate(zip(w["A"], w["B"]))]
        t0, c0 = time.perf_counter(), time.process_time()
        fit = fit_pose_pairs(pairs, "arm", z_mm=0.0, progress=True)
        t1, c1 = time.perf_counter(), time.process_time()
        _plain(w["A"], w["B"], 0.0)
        t2, c2 = time.perf_counter(), time.process_time()
        out[m] = {"fit_s": t1 - t0, "fit_cpu_s": c1 - c0, "plain_s": t2 - t1,
                  "plain_cpu_s": c2 - c1, "per_pair_ms": 1e3 * (c1 - c0) / m,
                  "outliers": len(fit.outliers), "findings": len(fit.findings)}
        print(f"handeye --poses, {m} pairs: {t1 - t0:.1f} s wall, {c1 - c0:.1f} s CPU "
              f"({1e3 * (c1 - c0) / m:.2f} ms a pair); plain least squares {c2 - c1:.1f} s CPU: "
              f"{(c1 - c0) / max(c2 - c1, 1e-9):.1f}x; {len(fit.outliers)} pairs left out, "
              f"{len(fit.findings)} findings")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--pairs", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=5000)
    ap.add_argument("--opencv-python", default=None,
                    help="a Python whose cv2 has calibrateRobotWorldHandEye (OpenCV 4)")
    ap.add_argument("--json", default=None, help="also write the figures here")
    ap.add_argument("--photos", action="store_true",
                    help="also compare with the photo-based handeye on the same robot")
    ap.add_argument("--probes", action="store_true", help="issue 40's broken files only")
    ap.add_argument("--speed", type=int, default=None, metavar="N",
                    help="the fit's cost with N pairs only (issue 41)")
    a = ap.parse_args()
    if a.probes or a.speed:
        figures = {}
        if a.probes:
            figures["probes"] = probes(list(range(a.first_seed, a.first_seed + a.seeds)))
        if a.speed:
            figures["speed"] = speed(a.speed)
        if a.json:
            Path(a.json).write_text(json.dumps(figures, indent=1))
        return
    if a.photos:
        photo_comparison(range(a.first_seed, a.first_seed + min(a.seeds, 10)))
    print(f"installed cv2 {cv2.__version__}: calibrateRobotWorldHandEye "
          f"{'present' if hasattr(cv2, 'calibrateRobotWorldHandEye') else 'absent'}")
    figures = {}
    for mount in ("arm", "fixed"):
        for noise, kw in NOISE.items():
            zs, times, falses, unseen, ocv, own, found = [], [], 0, 0, {}, [], 0
            for seed in range(a.first_seed, a.first_seed + a.seeds):
                w = simulate_pairs(TRUTH, a.pairs, seed=seed, mount=mount, **kw)
                pairs = [PosePair(str(i), p, q) for i, (p, q) in enumerate(zip(w["A"], w["B"]))]
                t0 = time.perf_counter()
                fit = fit_pose_pairs(pairs, mount, z_mm=float(w["Y"][2, 3]))
                times.append(time.perf_counter() - t0)
                free = fit_pose_pairs(pairs, mount)     # without the height: flagged?
                unseen += int(any(d["label"] == "X_z_mm" for d in free.not_identifiable))
                falses += len(fit.outliers)
                found += len(fit.findings)
                zs.append(_err(fit.X, w["X"]) / np.sqrt(np.diag(fit.cov))[:6])
                if mount == "arm":
                    res = (_opencv_there(a.opencv_python, w["A"], w["B"]) if a.opencv_python
                           else _opencv_here(w["A"], w["B"]))
                    for k, v in (res or {}).items():
                        if isinstance(v, str):
                            ocv.setdefault(k, []).append(v)
                            continue
                        e = _err(v[0], w["X"])
                        ocv.setdefault(k, []).append((np.linalg.norm(e[3:]), np.linalg.norm(e[:3]),
                                                      v[1], _pair_rms(w["A"], w["B"], v[0], v[2])))
                own.append(_pair_rms(w["A"], w["B"], fit.X, fit.Y) if mount == "arm" else 0.0)
            zs = np.array(zs)
            row = {"rms_error_over_std": np.sqrt(np.mean(zs**2, axis=0)).round(2).tolist(),
                   "within_2_std": float(np.mean(np.abs(zs) < 2.0)),
                   "false_outliers": falses, "false_findings": found,
                   "height_flagged": f"{unseen}/{a.seeds}",
                   "median_time_s": float(np.median(times))}
            print(f"{mount:5s} {noise:4s}: error/std RMS (rot x y z, t x y z) "
                  f"{row['rms_error_over_std']}, within 2 std {row['within_2_std']:.1%}, "
                  f"pairs falsely left out {falses} in {a.seeds} sets, findings {found}, "
                  "height flagged "
                  f"{row['height_flagged']}, {row['median_time_s'] * 1e3:.0f} ms")
            if mount == "arm":
                row["pair_rms_mm"] = float(np.median(own))
                print(f"        vision-cal: pairs' target RMS (median) {np.median(own):.3f} mm")
            for k, v in ocv.items():
                fails = [x for x in v if isinstance(x, str)]
                ok = np.array([x for x in v if not isinstance(x, str)])
                row[f"opencv_{k}"] = {"failed": f"{len(fails)}/{len(v)}"}
                if fails:
                    print(f"        OpenCV {k}: failed on {len(fails)}/{len(v)} sets ({fails[0]})")
                if len(ok):
                    row[f"opencv_{k}"].update(
                        {"median_t_err_mm": float(np.median(ok[:, 0])),
                         "median_r_err_deg": float(np.median(ok[:, 1])),
                         "median_time_s": float(np.median(ok[:, 2])),
                         "median_pair_rms_mm": float(np.median(ok[:, 3]))})
                    print(f"        OpenCV {k} ({len(ok)} sets): |t error| median "
                          f"{np.median(ok[:, 0]):.3f} mm, |rotation error| "
                          f"{np.median(ok[:, 1]):.3f} deg, pairs' target RMS "
                          f"{np.median(ok[:, 3]):.3f} mm, {np.median(ok[:, 2]) * 1e3:.2f} ms")
            figures[f"{mount}/{noise}"] = row
    if a.json:
        Path(a.json).write_text(json.dumps(figures, indent=1))


if __name__ == "__main__":
    main()
