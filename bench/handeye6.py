"""Hand-eye of any arm from photos and the robot's poses (issue 40): the estimator against the
six-axis world's truth over seeds, its refusals, and the real session against the plain
approaches.

``--seeds N`` (synthetic, worlds/six_axis.py: a UR5e-like arm off its controller's model,
joint noise, a lens the estimator is not told; projected corners with 0.15 px of detector
noise; the poses with the commanded joints unless ``--no-joints``): for each seed and mount,
12 photos fitted with the lens estimated; printed: the share of the 12 pose parameters
(T_robot_camera / T_flange_camera and T_flange_board / T_robot_board, rotation and
translation per axis) within 2 std of the truth (95 % when the stds are right), in the
world's frames and in the controller's (joint 1's zero and offset and joint 6's errors
absorbed: what no pose of the arm tells from the transforms), the RMS of error / std, the
share of 20 fresh photos' corners inside the 95 % radius stated for each (at poses inside
``valid_for.flange_poses`` and outside it), the verdict; a camera on the arm: the fresh
photos' corners located on the board's plane (``vision-cal locate``'s code) inside their
stated 95 % ellipse. ``--dh-mm`` adds kinematic errors (the controller's model off by that
much per DH length, a tenth of it in degrees per angle: a systematic, not a random, pose
error); ``--kinematic-length 0`` fits without the kinematic error term (the robot's pose
error independent from photo to photo, as before).

``--failures``: per seed, a lens declared 10 % long, poses in metres read as mm (and in
inches), poses shifted by one photo, a photo of another board (other squares): the outcome
(refused and the cause named, or the verdict and its first reason): never ready.

``--real``: the eight real photos of ``../shared/real_photos/industrial_charuco_even``:
each photo's residual and its prediction from the seven others (px, mm at the board), the
verdict, the 35 splits 4 + 4 (fit four, predict the other four), and the plain approaches on
the same detections: a joint least squares of the same unknowns (scipy, finite
differences, every corner alike), the same with each photo's flange free under a prior
(the sparse formulation), and, with ``--opencv-python`` (a Python whose cv2 is OpenCV 4:
``python -m venv /tmp/cv4 && /tmp/cv4/bin/pip install "opencv-contrib-python-headless<5"``),
OpenCV's calibrateCamera + solvePnP + calibrateRobotWorldHandEye (SHAH, LI) and
calibrateHandEye (TSAI, PARK, HORAUD, ANDREFF, DANIILIDIS; the board's place on the flange
averaged): each photo predicted from a fit of the others.

    python bench/handeye6.py --seeds 20 --failures --real --opencv-python /tmp/cv4/bin/python
"""

from __future__ import annotations

import argparse
import itertools
import subprocess
import sys
import tempfile
import textwrap
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from vision_cal.camera import handeye_locate, handeye_valid
from vision_cal.camera.board import find_board, load_board
from vision_cal.camera.handeye import HandeyeFit, estimated_lens_fit, fit_handeye
from vision_cal.camera.handeye_closed import inv_T
from vision_cal.camera.handeye_lsq import Problem, View, lens_vector, refine
from vision_cal.camera.handeye_stats import predicted_covariance
from vision_cal.camera.handeye_verdict import judge_handeye, lens_check
from vision_cal.camera.robot_poses import pair_with_photos, read_robot_poses
from vision_cal.config import DEFAULT
from vision_cal.estimate.verdict import R95_PER_RMS
from vision_cal.dataset.photos import list_photos, load_photo
from vision_cal.errors import VisionCalError
from vision_cal.sheet.charuco import charuco_spec, make_charuco_layout

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.camera.handeye_helpers import from_fit, pose_offset  # noqa: E402
from worlds.six_axis import make_world, observe, shots  # noqa: E402
REAL = ROOT.parent / "shared" / "real_photos" / "industrial_charuco_even"


def stated_new_px(fit: HandeyeFit, view: View, *, credit: bool = True) -> float:
    """The RMS (px per corner, 2-D) ``fit`` states for the board's points of ``view`` seen
    from a new pose (its pixels are not used): the unknowns' covariance, the corners' noise
    and the robot's pose error there, less what the unknowns took of the kinematic error
    there (``credit`` False: none), raised by ``inflation``."""
    pr = Problem([view], fit.mount, fit.X, fit.Y, fit.lens, fit.free)
    Js, Jd = pr.jacobians(pr.start())
    cross = (None if fit.shared is None or not credit
             else fit.shared.cross(view.T_robot_flange, view.joints_deg))
    C = predicted_covariance(Js, Jd, fit.cov, fit.noise, cross, fit.inflation)
    return float(np.sqrt(np.trace(C) / len(view.px)))


def _T(R=None, t=None) -> np.ndarray:
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if t is not None:
        T[:3, 3] = t
    return T


def _rot(rotvec_deg) -> np.ndarray:
    return Rotation.from_rotvec(np.radians(rotvec_deg)).as_matrix()


def controller_frames(w) -> tuple[np.ndarray, np.ndarray]:
    """(X, Y) in the frames the controller's model defines: the true arm is
    ``C_base F'(q) C_flange`` with ``F'`` its inner joints' errors only, ``C_base`` the
    turn and lift of joint 1's zero and offset along its axis (the whole arm turned or
    lifted) and ``C_flange`` joint 6's errors (the flange moved on the last link). No
    pose of the arm tells these apart from where the camera and the board are: any
    hand-eye against the controller's poses finds X and Y with them absorbed, and they
    are the ones that put a commanded pose where the camera saw it."""
    n, t = w.nominal, w.true
    Cb = _T(_rot([0.0, 0.0, t.theta0_deg[0] - n.theta0_deg[0]]),
            [0.0, 0.0, t.d_mm[0] - n.d_mm[0]])
    a0, al0 = n.a_mm[5], n.alpha_deg[5]
    Cf = (_T(_rot([-al0, 0.0, 0.0])) @ _T(t=[-a0, 0.0, 0.0])
          @ _T(_rot([0.0, 0.0, t.theta0_deg[5] - n.theta0_deg[5]]),
               [0.0, 0.0, t.d_mm[5] - n.d_mm[5]])
          @ _T(t=[t.a_mm[5], 0.0, 0.0]) @ _T(_rot([t.alpha_deg[5], 0.0, 0.0])))
    if w.mount == "fixed":
        return inv_T(Cb) @ w.X, Cf @ w.Y
    return Cf @ w.X, inv_T(Cb) @ w.Y


def _views(w, sh, rng, joints: bool = True):
    """The world's photos as the estimator gets them: the controller's pose (and commanded
    joints, unless ``joints`` is False) and the corners the detector reports."""
    return [View(s.name, s.T_robot_flange, *observe(w, s, rng),
                 joints_deg=s.q_deg if joints else None) for s in sh]


def _predict_err(views, mount, X, Y, lens) -> np.ndarray:
    """(N,) each corner's 2-D error (px) predicted from the robot's poses alone."""
    pr = Problem(views, mount, X, Y, lens, np.zeros(9, bool))
    return np.linalg.norm(pr.predict(pr.start()) - pr.px, axis=1)


def _predict_rms(views, mount, X, Y, lens) -> float:
    return float(np.sqrt(np.mean(_predict_err(views, mount, X, Y, lens) ** 2)))


def _fresh(f, views, mount) -> tuple[list, list, int]:
    """Fresh photos predicted from ``f``, each corner's error against the stated 95 %
    radius: (inside valid_for: each photo's share of corners inside, outside: the same,
    how many outside)."""
    vf = handeye_valid.of_views(f.views, lever_mm=f.noise.lever_mm or 1.0,
                                length_rad=DEFAULT.handeye_photos.kinematic_length_rad)
    inside, outside = [], []
    for v in views:
        e = _predict_err([v], mount, f.X, f.Y, f.lens)
        st = stated_new_px(f, v)
        out = handeye_valid.check(vf, cal="", ids=[v.name], poses=[v.T_robot_flange],
                                  joints=[v.joints_deg])
        (outside if out else inside).append(np.mean(e <= R95_PER_RMS * st))
    return inside, outside, len(outside)


def _located(f, w, fresh_shots, joints: bool) -> tuple[list, list]:
    """A camera on the arm used: each fresh photo's board corners (projected, the pixel
    exact) located on the board's plane from the controller's flange pose
    (``camera/handeye_locate``), against the board's corners in the controller's frames:
    the share of corners inside their stated 95 % ellipse (x, y), at poses inside and
    outside valid_for."""
    cam = from_fit(f)
    vf = handeye_valid.of_views(f.views, lever_mm=f.noise.lever_mm or 1.0,
                                length_rad=DEFAULT.handeye_photos.kinematic_length_rad)
    _, Yc = controller_frames(w)
    C = w.board.corners()
    inside, outside = [], []
    for s in fresh_shots:
        q = s.q_deg if joints else None
        P = C @ s.T_camera_board[:3, :3].T + s.T_camera_board[:3, 3]
        pts = handeye_locate.locate_at(cam, s.T_robot_flange, w.lens.project(P), 0.0,
                                       joints=q)
        e = np.array([p.robot_mm - (Yc[:3, :3] @ c + Yc[:3, 3]) for p, c in zip(pts, C)])
        sd = np.array([p.robot_std_mm for p in pts])
        d2 = np.sum((e[:, :2] / sd[:, :2]) ** 2, axis=1)
        out = handeye_valid.check(vf, cal="", ids=[s.name], poses=[s.T_robot_flange],
                                  joints=[q])
        (outside if out else inside).append(float(np.mean(d2 <= CHI2_2_95)))
    return inside, outside


#: chi-square with 2 degrees of freedom at 95 %
CHI2_2_95 = 5.991


def synthetic(seeds, mount: str, n: int, dh_mm: float, joint_deg: float, *, joints=True,
              config=None) -> None:
    """Parameters against the truth (the world's frames, and the controller's: joint 1's
    zero and offset and joint 6's errors absorbed, which no pose can tell from the
    transforms), the stated error for a new pose against fresh photos of the same world,
    inside and outside valid_for."""
    zw, zc, status, zlens, inside, outside, n_out = [], [], {}, [], [], [], 0
    loc_in, loc_out = [], []
    for seed in seeds:
        w = make_world(seed, mount=mount, joint_noise_deg=joint_deg, dh_error_mm=dh_mm,
                       dh_error_deg=dh_mm / 10.0)
        rng = np.random.default_rng(seed + 1)
        sh = shots(w, n + 20, seed)
        views = _views(w, sh, rng, joints)
        f = fit_handeye(views[:n], mount, w.lens.size_px, config=config)
        zw.append(np.r_[pose_offset(w.X, f.X), pose_offset(w.Y, f.Y)] / f.std[:12])
        Xc, Yc = controller_frames(w)
        zc.append(np.r_[pose_offset(Xc, f.X), pose_offset(Yc, f.Y)] / f.std[:12])
        truth = lens_vector(w.lens.K, w.lens.dist)
        zlens.append(((f.lens - truth)[f.free] / f.std[12:])[:4])
        ins, outs, k = _fresh(f, views[n:], mount)
        inside += ins
        outside += outs
        n_out += k
        if mount == "arm":
            li, lo = _located(f, w, sh[n:], joints)
            loc_in += li
            loc_out += lo
        v = judge_handeye(f).status
        status[v] = status.get(v, 0) + 1
        print(f"  seed {seed}: within 2 std {np.mean(np.abs(zw[-1]) < 2):.2f} (controller's "
              f"frames {np.mean(np.abs(zc[-1]) < 2):.2f}), fresh photos inside the stated 95 % "
              f"radius {np.mean(ins) if ins else float('nan'):.2f} ({len(ins)} inside "
              f"valid_for), {np.mean(outs) if outs else float('nan'):.2f} ({k} outside); "
              f"kinematic {f.noise.kin_mm:.3f} mm over {f.noise.kin_over or '-'}; {v}",
              flush=True)
    zw, zc = np.array(zw), np.array(zc)
    share = 100 * np.mean(inside) if inside else float("nan")
    print(f"{mount}, {n} photos, joint noise {joint_deg} deg, DH error {dh_mm} mm, joints "
          f"{'given' if joints else 'not given'}: pose parameters within 2 std "
          f"{100 * np.mean(np.abs(zw) < 2):.1f} % of {zw.size} (error/std RMS "
          f"{np.sqrt(np.mean(zw ** 2)):.2f}), in the controller's frames "
          f"{100 * np.mean(np.abs(zc) < 2):.1f} % ({np.sqrt(np.mean(zc ** 2)):.2f}); fx fy cx "
          f"cy within 2 std {100 * np.mean(np.abs(np.array(zlens)) < 2):.1f} %; fresh "
          f"corners inside the stated 95 % radius: {share:.1f} % at poses inside valid_for "
          f"({len(inside)} photos), "
          f"{100 * np.mean(outside) if outside else float('nan'):.1f} % outside ({n_out} "
          f"photos flagged), {100 * np.mean(inside + outside):.1f} % all; verdicts {status}")
    if loc_in or loc_out:
        print(f"  located (vision-cal locate, the board's plane): corners inside their stated "
              f"95 % ellipse {100 * np.mean(loc_in) if loc_in else float('nan'):.1f} % at "
              f"poses inside valid_for ({len(loc_in)} photos), "
              f"{100 * np.mean(loc_out) if loc_out else float('nan'):.1f} % outside "
              f"({len(loc_out)})")


def _outcome(fn, views=None) -> str:
    """The case's outcome; with ``views`` the lens was declared, and is judged against one
    estimated from the same photos (as the command does)."""
    try:
        f = fn()
    except VisionCalError as e:
        return f"refused: {e.reason[:110]}"
    said = lens_check(f, estimated_lens_fit(views, f)) if views is not None else None
    v = judge_handeye(f, lens_check=said)
    return f"{v.status}: {v.reasons[0][:110] if v.reasons else ''}"


def failures(seeds) -> None:
    """Each failure case: refused with its cause, or flagged; never ready."""
    ready = 0
    cases = 0
    for seed in seeds:
        w = make_world(seed, mount="fixed", joint_noise_deg=0.02)
        rng = np.random.default_rng(seed + 1)
        views = _views(w, shots(w, 10, seed), rng)
        K10 = w.lens.K.copy()
        K10[:2, :2] *= 1.1

        def scaled(s):
            out = []
            for v in views:
                T = v.T_robot_flange.copy()
                T[:3, 3] *= s
                out.append(View(v.name, T, v.ids, v.board_mm, v.px))
            return out

        shifted = [View(v.name, views[i + 1].T_robot_flange, v.ids, v.board_mm, v.px)
                   for i, v in enumerate(views[:-1])]
        other = make_world(seed, mount="fixed", joint_noise_deg=0.02,
                           board={"square_mm": 30.0, "marker_mm": 15.0})
        o = shots(other, 4, seed)[3]
        ids, _, px = observe(other, o, rng)
        another = list(views)
        another[3] = View(views[3].name, views[3].T_robot_flange, ids, views[3].board_mm, px)
        size = w.lens.size_px
        res = {"lens 10 % long": lambda: fit_handeye(views, "fixed", size,
                                                        lens=(K10, w.lens.dist)),
               "metres as mm": lambda: fit_handeye(scaled(1e-3), "fixed", size, units="mm"),
               "inches as mm": lambda: fit_handeye(scaled(1 / 25.4), "fixed", size, units="mm"),
               "shifted by one": lambda: fit_handeye(shifted, "fixed", size),
               "another board": lambda: fit_handeye(another, "fixed", size)}
        for name, fn in res.items():
            out = _outcome(fn, views if name.startswith("lens") else None)
            cases += 1
            ready += out.startswith("ready")
            print(f"  seed {seed}, {name}: {out}", flush=True)
    print(f"failure cases: {cases}, ready: {ready}")


# --------------------------------------------------------------------------- the real session

def real_views() -> list[View]:
    """The eight real photos' saddles (a ChArUco board of `sheet --charuco`)."""
    spec = charuco_spec((5, 7), 36.195, 18.256, "DICT_6X6_250")
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "sheet.json"
        import json

        p.write_text(json.dumps(make_charuco_layout(spec).to_sheet_json()))
        board = load_board(p)
    photos = list_photos(REAL / "images")
    poses, _ = read_robot_poses(REAL / "poses")
    poses = pair_with_photos(poses, photos, str(REAL / "poses"))
    views = []
    for name, pose in zip(photos, poses):
        img, _, _ = load_photo(REAL / "images", name)
        pts = find_board(img, board)
        views.append(View(name, pose.T, pts.ids, pts.board_mm, pts.px))
    return views


def _plain(views, X0, Y0, lens0, free):
    """A joint least squares of the same unknowns, every corner alike (scipy, finite
    differences, its own projection: OpenCV's model)."""
    import cv2   # the plain approach's own projection

    def T(v):
        M = np.eye(4)
        M[:3, :3] = Rotation.from_rotvec(v[:3]).as_matrix()
        M[:3, 3] = v[3:6]
        return M

    def pred(p, v):
        L = lens0.copy()
        L[free] = p[12:]
        M = np.linalg.inv(T(p[:6])) @ v.T_robot_flange @ T(p[6:12])
        K = np.array([[L[0], 0, L[2]], [0, L[1], L[3]], [0, 0, 1]])
        return cv2.projectPoints(v.board_mm, cv2.Rodrigues(M[:3, :3])[0], M[:3, 3], K,
                                 L[4:])[0].reshape(-1, 2)

    p0 = np.r_[Rotation.from_matrix(X0[:3, :3]).as_rotvec(), X0[:3, 3],
               Rotation.from_matrix(Y0[:3, :3]).as_rotvec(), Y0[:3, 3], lens0[free]]
    p = least_squares(lambda q: np.concatenate([(pred(q, v) - v.px).ravel() for v in views]),
                      p0, x_scale="jac").x
    return lambda v: pred(p, v)


def _loo(views, fit_fn) -> tuple[float, list]:
    errs = []
    for k in range(len(views)):
        predict = fit_fn(views[:k] + views[k + 1:])
        errs.append(predict(views[k]) - views[k].px)
    per = [float(np.sqrt(np.mean(np.sum(e ** 2, axis=1)))) for e in errs]
    return float(np.sqrt(np.mean(np.sum(np.vstack(errs) ** 2, axis=1)))), per


_OPENCV4 = textwrap.dedent("""
    import sys, json, numpy as np, cv2
    d = np.load(sys.argv[1], allow_pickle=True)
    views = d["views"]; size = tuple(int(s) for s in d["size"])
    out = {}
    def T(R, t):
        M = np.eye(4); M[:3, :3] = R; M[:3, 3] = np.ravel(t); return M
    for k in range(len(views)):
        fit = [v for i, v in enumerate(views) if i != k]
        objs = [np.asarray(v[1], np.float32) for v in fit]
        imgs = [np.asarray(v[2], np.float32) for v in fit]
        rms, K, dist, rv, tv = cv2.calibrateCamera(objs, imgs, size, None, None)
        C = [T(cv2.Rodrigues(r)[0], t) for r, t in zip(rv, tv)]      # T_camera_board
        F = [np.asarray(v[0], float) for v in fit]                    # T_robot_flange
        ho = views[k]
        res = {}
        # robot-world: world = board, base = flange, gripper = robot base (camera fixed)
        for m in ("SHAH", "LI"):
            try:
                Rb, tb, Rg, tg = cv2.calibrateRobotWorldHandEye(
                    [c[:3, :3] for c in C], [c[:3, 3] for c in C],
                    [f[:3, :3] for f in F], [f[:3, 3] for f in F],
                    method=getattr(cv2, "CALIB_ROBOT_WORLD_HAND_EYE_" + m))
                X = np.linalg.inv(T(Rg, tg)); Y = np.linalg.inv(T(Rb, tb))
                res["RW_" + m] = (X, Y)
            except cv2.error as e:
                res["RW_" + m] = str(e).splitlines()[-1]
        # hand-eye, eye-to-hand: the flange poses inverted give the camera in the base
        Fi = [np.linalg.inv(f) for f in F]
        for m in ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS"):
            try:
                R, t = cv2.calibrateHandEye([f[:3, :3] for f in Fi], [f[:3, 3] for f in Fi],
                                            [c[:3, :3] for c in C], [c[:3, 3] for c in C],
                                            method=getattr(cv2, "CALIB_HAND_EYE_" + m))
                X = T(R, t)                                 # T_robot_camera
                Ys = [np.linalg.inv(f) @ X @ c for f, c in zip(F, C)]
                Ym = np.mean(Ys, axis=0); U, _, Vt = np.linalg.svd(Ym[:3, :3])
                Y = T(U @ Vt, Ym[:3, 3])
                res["HE_" + m] = (X, Y)
            except cv2.error as e:
                res["HE_" + m] = str(e).splitlines()[-1]
        for name, r in res.items():
            if isinstance(r, str):
                out.setdefault(name, []).append(None); continue
            X, Y = r
            M = np.linalg.inv(X) @ np.asarray(ho[0], float) @ Y
            uv = cv2.projectPoints(np.asarray(ho[1], float), cv2.Rodrigues(M[:3, :3])[0],
                                   M[:3, 3], K, dist)[0].reshape(-1, 2)
            out.setdefault(name, []).append((uv - np.asarray(ho[2], float)).tolist())
    print(json.dumps({"version": cv2.__version__, "out": out}))
""")


def opencv4(python: str, views, size) -> None:
    """OpenCV 4's hand-eye in another Python, each photo predicted from the others."""
    import json

    with tempfile.TemporaryDirectory() as d:
        src, script = Path(d) / "in.npz", Path(d) / "cv.py"
        arr = np.empty(len(views), dtype=object)
        for i, v in enumerate(views):
            arr[i] = (v.T_robot_flange, v.board_mm, v.px)
        np.savez(src, views=arr, size=np.array(size))
        script.write_text(_OPENCV4)
        r = subprocess.run([python, str(script), str(src)], capture_output=True, text=True,
                           timeout=600)
    if r.returncode:
        print("  OpenCV 4: failed:", r.stderr.strip().splitlines()[-1:])
        return
    res = json.loads(r.stdout)
    for name, errs in res["out"].items():
        if any(e is None for e in errs):
            print(f"  OpenCV {res['version']} {name}: failed on {sum(e is None for e in errs)}"
                  " of the held-out fits")
            continue
        e = np.vstack([np.array(x) for x in errs])
        per = [float(np.sqrt(np.mean(np.sum(np.array(x) ** 2, axis=1)))) for x in errs]
        print(f"  OpenCV {res['version']} calibrateCamera + {name}: held out "
              f"{np.sqrt(np.mean(np.sum(e ** 2, axis=1))):.2f} px RMS "
              f"(per photo {' '.join(f'{x:.2f}' for x in per)})")


def real(opencv_python: str | None) -> None:
    views = real_views()
    size = (1600, 1200)
    f = fit_handeye(views, "fixed", size)
    obs, st, omm, smm = f.heldout_rms()
    print(f"real session, 8 photos: lens models {[(t, round(o, 3)) for t, o in f.lens_models]}")
    for h in f.heldout:
        print(f"  {h.name}: residual {f.residual_px[h.name]:.2f} px, held out {h.rms_px:.2f} px"
              f" ({h.rms_mm:.2f} mm at the board), stated {h.stated_px * f.inflation:.2f} px")
    v = judge_handeye(f)
    print(f"  held out {obs:.3f} px ({omm:.3f} mm), stated {st:.3f} px ({smm:.3f} mm), "
          f"inflation {f.inflation:.2f}; noise {f.noise}; {v.status}: {v.reasons}")
    terms = [n for n, fr in zip(("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"), f.free)
             if fr]
    free = f.free.copy()
    start_X, start_Y = f.start.Z, f.start.X
    lens0 = f.lens.copy()
    lens0[4:] = 0.0
    plain, per = _loo(views, lambda vs: _plain(vs, start_X, start_Y, lens0, free))
    print(f"  plain joint least squares ({' '.join(terms)}): held out {plain:.3f} px "
          f"(per photo {' '.join(f'{x:.2f}' for x in per)})")
    for sig in ((0.02, 0.2), (0.05, 0.5)):
        def re_fit(vs, sig=sig):
            R = refine(Problem(vs, "fixed", f.X, f.Y, f.lens, free, sigma_px=f.noise.sigma_px,
                               pose_sigma=sig))
            return lambda v: (Problem([v], "fixed", R.X, R.Y, R.lens, np.zeros(9, bool))
                              .predict(np.zeros(12)))
        re, per = _loo(views, re_fit)
        print(f"  each photo's flange free under a prior {sig} (deg, mm; sparse Jacobian): "
              f"held out {re:.3f} px (per photo {' '.join(f'{x:.2f}' for x in per)})")
    if opencv_python:
        opencv4(opencv_python, views, size)
    halves(views, size)


def halves(views, size) -> None:
    """Fit four photos, predict the other four: the 35 splits."""
    rows = []
    for half in itertools.combinations(range(8), 4):
        if 0 not in half:
            continue
        a = [views[i] for i in half]
        b = [views[i] for i in range(8) if i not in half]
        try:
            f = fit_handeye(a, "fixed", size)
        except VisionCalError as e:
            print(f"  halves {half}: {e}")
            continue
        act = _predict_rms(b, "fixed", f.X, f.Y, f.lens)
        rows.append((f.heldout_rms()[1], act, judge_handeye(f).status))
    r = np.array([x[:2] for x in rows])
    print(f"  4 + 4 halves ({len(rows)} splits): the other half predicted "
          f"{np.sqrt(np.mean(r[:, 1] ** 2)):.2f} px RMS (median {np.median(r[:, 1]):.2f}), "
          f"stated {np.sqrt(np.mean(r[:, 0] ** 2)):.2f}; "
          f"covered in {np.sum(r[:, 1] <= r[:, 0])}/{len(r)}; verdicts "
          f"{dict(zip(*np.unique([x[2] for x in rows], return_counts=True)))}")


def rendered(seeds, mount: str, n: int) -> None:
    """Photos rendered by the world (its own print of OpenCV's board through its lens),
    read by the command as a user's folder: the board's saddles detected, the poses read
    from the world's ROS-style files, the lens estimated."""
    from vision_cal.actions.handeye import HandeyePhotosRequest, handeye_photos
    from vision_cal.actions.sheet import SheetRequest, sheet
    from worlds.six_axis import write_session

    z = []
    for seed in seeds:
        w = make_world(seed, mount=mount, joint_noise_deg=0.02)
        with tempfile.TemporaryDirectory() as d:
            d = Path(d)
            write_session(d / "s", w, n, seed)
            sheet(SheetRequest(out=str(d / "b"), charuco="5x7", square_mm=w.board.square_mm,
                               marker_mm=w.board.marker_mm, dictionary=w.board.dictionary,
                               quiet=True))
            out = handeye_photos(HandeyePhotosRequest(
                folder=str(d / "s" / "images"), robot_poses=str(d / "s" / "poses"),
                sheet=str(d / "b" / "sheet.json"), mount=mount, out=str(d / "o"), quiet=True))
        f = out.fit
        err = np.r_[pose_offset(w.X, f.X), pose_offset(w.Y, f.Y)]
        z.append(err / f.std[:12])
        fresh = _views(w, shots(w, 20, seed + 99), np.random.default_rng(seed))
        e = _predict_rms(fresh, mount, f.X, f.Y, f.lens)
        print(f"  rendered seed {seed} ({mount}): {len(f.views)} photos, within 2 std "
              f"{np.mean(np.abs(z[-1]) < 2):.2f}, |error|/std max {np.abs(z[-1]).max():.2f}, "
              f"held out {f.heldout_rms()[0]:.2f} px, stated {f.heldout_rms()[1]:.2f}, fresh "
              f"poses {e:.2f}; {out.document['verdict']['status']}", flush=True)
    z = np.array(z)
    print(f"rendered ({mount}): pose parameters within 2 std {100 * np.mean(np.abs(z) < 2):.1f} %"
          f" ({z.size})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=0)
    ap.add_argument("--first-seed", type=int, default=7000)
    ap.add_argument("--photos", type=int, default=12)
    ap.add_argument("--dh-mm", type=float, default=0.0)
    ap.add_argument("--joint-deg", type=float, default=0.02)
    ap.add_argument("--mounts", default="fixed,arm")
    ap.add_argument("--failures", type=int, default=0, help="seeds of failure cases")
    ap.add_argument("--real", action="store_true")
    ap.add_argument("--render", type=int, default=0, help="seeds of rendered photos")
    ap.add_argument("--opencv-python", default=None)
    ap.add_argument("--no-joints", action="store_true",
                    help="the poses without the arm's joints (the kinematic error's "
                         "correlation over flange poses, valid_for without joints)")
    ap.add_argument("--kinematic-length", type=float, default=None,
                    help="config.handeye_photos.kinematic_length_rad (0: no kinematic term)")
    a = ap.parse_args()
    seeds = range(a.first_seed, a.first_seed + a.seeds)
    cfg = (None if a.kinematic_length is None else
           replace(DEFAULT.handeye_photos, kinematic_length_rad=a.kinematic_length))
    for mount in a.mounts.split(","):
        if a.seeds:
            synthetic(seeds, mount, a.photos, a.dh_mm, a.joint_deg, joints=not a.no_joints,
                      config=cfg)
    if a.render:
        for mount in a.mounts.split(","):
            rendered(range(a.first_seed + 900, a.first_seed + 900 + a.render), mount, a.photos)
    if a.failures:
        failures(range(a.first_seed + 500, a.first_seed + 500 + a.failures))
    if a.real:
        real(a.opencv_python)


if __name__ == "__main__":
    main()
