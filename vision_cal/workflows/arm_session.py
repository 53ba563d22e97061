"""A dataset of photos taken by the arm's camera: session.json ``poses``, measured and fitted.

session.json (``docs/format.md``, "Cameras")::

    "camera": {"size_px": [w, h], "K": [[...]], "dist": [...]},     required: declared lens
    "camera_mount": "flange",           "flange" (turns with joint 4) or "link2"
    "poses": [ {"image": "pose_000.png", "joints_deg": [q1, q2], "j4_deg": 30.0} ]

with the contract's ``sheet`` (the marker field, ``vision-cal sheet --field``) and
``robot`` blocks. ``marks`` may be absent. Each photo's marker corners come from the
measurement stage's own detector and sub-pixel edge fit (``measure/aruco.py``); a photo
that cannot be used is skipped with its reason and the others go on.
"""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from vision_cal.estimate.plausible import RADIAN_RANGE, radians_given
from vision_cal.camera.arm import (MAX_POSES, MIN_POSES, ArmView, check_declared_lens,
                                   estimate_lens, fit_arm_camera, without_misdetected)
from vision_cal.camera.fixed import UNDETERMINED
from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.dataset.camera_block import read_lens
from vision_cal.dataset.io import read_json
from vision_cal.dataset.marker_geometry import marker_geometry
from vision_cal.dataset.photos import PhotoRefused, load_photo, normalise_name
from vision_cal.dataset.fields import FieldReader
from vision_cal.dataset.session import read_robot_block, read_sheet_block
from vision_cal.dataset.valid_for import build as valid_for_block
from vision_cal.estimate.verdict import judge_camera_poses
from vision_cal.errors import CalibrationError, Failure, VisionCalError
from vision_cal.measure.workers import exit_with_parent
from vision_cal.progress import bar
from vision_cal.model.kinematics import ScaraParams
from vision_cal.model.motion import approach_signs
from vision_cal.measure.aruco import corners_from_edges, edge_points, find_sheet_markers
from vision_cal.measure.mapping import distort_px, undistort_px

MOUNTS = ("flange", "link2")
FORMAT = "vision-cal/1"


def read_arm_session(folder):
    """(folder, sheet, nominal ScaraParams, (size_px, K, dist), mount, poses) where poses is a
    list of (image, q_deg (2,), j4_deg); every field checked, one line naming it."""
    folder = Path(folder)
    path = folder / "session.json"
    if folder.is_dir() and not path.exists():
        raise VisionCalError("missing: a camera-on-arm folder needs a session.json (the poses "
                             "the photos were taken at): `vision-cal design --camera-on-arm` "
                             "writes it", file=str(path))
    raw = read_json(path)
    r = FieldReader(str(path))
    fmt = r.get(raw, "format", "")
    if fmt != FORMAT:
        r.fail("format", f"expected {FORMAT!r}, got {fmt!r}")
    robot = read_robot_block(r, r.get(raw, "robot", ""), "robot")
    sheet = read_sheet_block(r, r.get(raw, "sheet", ""), "sheet")
    cam = raw.get("camera")
    camera = None if cam is None else read_lens(r, cam, "camera")  # the one validator
    mount = raw.get("camera_mount", "flange")
    if mount not in MOUNTS:
        r.fail("camera_mount", f"expected one of {', '.join(MOUNTS)}, got {mount!r}")
    poses = []
    listed = r.list_(r.get(raw, "poses", ""), "poses", nonempty=True)
    if len(listed) > MAX_POSES:
        r.fail("poses", f"{len(listed)} poses: at most {MAX_POSES} (more adds nothing the fit "
                        "can use, and measuring them would take hours); keep a subset")
    for i, p in enumerate(listed):
        w = f"poses[{i}]"
        try:
            img = normalise_name(r.string(r.get(p, "image", w), f"{w}.image"))
        except ValueError as e:
            r.fail(f"{w}.image", f"{e}: the photos sit in the folder beside session.json")
        q = r.angles(r.get(p, "joints_deg", w), f"{w}.joints_deg")
        j4 = r.number(p.get("j4_deg", 0.0), f"{w}.j4_deg")
        if mount == "link2" and j4 != 0.0:
            r.fail(f"{w}.j4_deg", "a camera on link 2 does not turn with joint 4: leave "
                                  "j4_deg out or set camera_mount: flange")
        poses.append((img, np.asarray(q, float), float(j4)))
    if radians_given([q for _, q, _ in poses]):
        r.fail("poses", f"every joint angle is within +-{RADIAN_RANGE:.2f}: written in radians? "
                        "joints_deg are degrees (multiply by 57.2958)")
    nominal = ScaraParams(robot.L1_mm, robot.L2_mm, robot.joint_zero_deg[0],
                          robot.joint_zero_deg[1], robot.base_mm[0], robot.base_mm[1])
    # each joint's approach (the format's rule: its last motion, over every pose in order)
    signs = approach_signs([q for _, q, _ in poses], robot.home_deg)
    poses = [(img, q, j4, tuple(float(v) for v in sg)) for (img, q, j4), sg in zip(poses, signs)]
    return folder, sheet, nominal, camera, mount, poses, robot.repeatability_mm


def repeat_pairs(views) -> list[tuple[int, int]]:
    """(i, j) of photos taken at the same command (joints 1, 2 and 4) reached from the same
    sides, each with the one before it at that command: what the robot's repeatability
    alone moves apart."""
    last: dict[tuple, int] = {}
    out = []
    for k, v in enumerate(views):
        key = (tuple(np.round(np.asarray(v.q_deg, float), 6)), round(float(v.j4_deg), 6),
               tuple(v.approach))
        if key in last:
            out.append((last[key], k))
        last[key] = k
    return out


def undetermined_reasons(fit, mount: str, *, undetermined: bool = False) -> list[tuple[str, str]]:
    """(status, sentence) of what the poses leave undetermined whatever the lens (the
    camera's height, where only the lens's focal length leaves it open, is the lens's
    sentence: :func:`lens_height_reason`, or the undetermined lens's own)."""
    out = []
    ni = [n for n in fit.not_identifiable_given_lens
          if not (undetermined and n == "cam_z_mm")]
    if ni:
        out.append(("not reliable", "the poses do not separate "
                    + ", ".join(ni)
                    + (" from the rest (turn joint 4 between photos: vision-cal design "
                       "--camera-on-arm)" if mount == "flange" else
                       " from the rest (a camera on link 2 cannot separate L2 from its own "
                       "offset along it)")))
    return out


#: the height above the sheet ``lens_height_reason`` states a point's std at (mm)
ABOVE_MM = 50.0


def lens_height_reason(fit, K) -> list[tuple[str, str]]:
    """``check`` when an estimated lens leaves the camera's height open beyond
    :data:`~vision_cal.camera.arm.UNIDENTIFIED_STD` (its focal length and the height trade:
    the sheet's plane is not affected, a point above it is), with the std of the height,
    of the focal length, and of a point :data:`ABOVE_MM` above the sheet at the view's
    edge, and what would fix it."""
    if "cam_z_mm" not in fit.not_identifiable or "cam_z_mm" in fit.not_identifiable_given_lens:
        return []
    k = fit.labels.index("cam_z_mm")
    h_sd = float(np.sqrt(fit.cov[k, k]))
    f_sd = float(np.sqrt(fit.cov[fit.labels.index("f_px"), fit.labels.index("f_px")]))
    height = abs(float(fit.T_flange_camera[2, 3]))
    # a point at the edge of the view (half the height away) ABOVE_MM up: its place moves
    # by that distance times the height's relative error over what is left of the height
    edge = 0.5 * height * ABOVE_MM / max(height - ABOVE_MM, 1e-9) * h_sd / max(height, 1e-9)
    return [("check", f"the lens was estimated from the views (focal length {K[0, 0]:.0f} +- "
                      f"{f_sd:.0f} px), which trades with the camera's height: T_flange_camera's"
                      f" z is known to {h_sd:.2g} mm, a point {ABOVE_MM:g} mm above the sheet to "
                      f"about {edge:.2g} mm (the sheet's plane is not affected; locate states "
                      "it); declare camera K in session.json, or tilt the camera 15 deg or "
                      "more")]


def _pose_table(views, fit) -> list[dict]:
    """Per photo: its command, the in-plane flange residual and its corner-noise std."""
    return [{"image": v.file, "joints_deg": [float(a) for a in v.q_deg], "j4_deg": v.j4_deg,
             "approach": [int(a) for a in v.approach],
             "residual_mm": [float(a) for a in r], "sigma_mm": float(s),
             "heldout_residual_mm": [float(a) for a in h]}
            for v, r, s, h in zip(views, fit.flange_residual_mm, fit.flange_sigma_mm,
                                  fit.flange_heldout_mm)]


def corners_in_lens(edges, fallback, K=None, dist=None) -> np.ndarray:
    """Marker corners (M, 4, 2) in raw px: the border edges fitted as straight lines in
    the lens's ideal pixels, as the pen measurement does
    (``measure/types.ImageDetections.corners_for``). A marker's straight edge is curved in
    a distorted photo; a straight line fitted to it there biases the corner by a few
    hundredths of a pixel, differently across the image: with k1 -0.045 declared and
    nothing else missing, that bias put the arm camera's residual 1.4 times its floor."""
    fallback = np.asarray(fallback, float).reshape(-1, 4, 2)
    if edges is None:
        return fallback
    if K is None or dist is None or not np.any(np.asarray(dist, float)):
        return corners_from_edges(edges, fallback)
    e = np.asarray(edges, float)
    ideal = undistort_px(e.reshape(-1, 2), K, dist).reshape(e.shape)
    c0 = undistort_px(fallback.reshape(-1, 2), K, dist).reshape(-1, 4, 2)
    c = corners_from_edges(ideal, c0)
    return distort_px(c.reshape(-1, 2), K, dist).reshape(-1, 4, 2)


def in_lens(view: ArmView, K, dist) -> ArmView:
    """The view with its corners found again in the lens ``(K, dist)``'s ideal pixels."""
    if view.edges_px is None:
        return view
    c = corners_in_lens(view.edges_px, view.detected_px, K, dist)
    return replace(view, corners_px=np.asarray(c, float).reshape(-1, 2))


@dataclass(frozen=True)
class SkippedPhoto(Failure):
    """A photo :func:`measure_view` could not use, and why (falsy; reading an
    :class:`ArmView`'s attribute from it raises with the reason)."""

    file: str
    reason: str

    def to_json(self) -> dict:
        """Its calibration.json ``images[]`` entry."""
        return {"file": self.file, "status": "skipped", "reason": self.reason}


def _skipped(image: str, reason: str) -> tuple[SkippedPhoto, dict]:
    s = SkippedPhoto(image, reason)
    return s, s.to_json()


def measure_view(folder, sheet, size, image: str, q, j4, approach=(1.0, 1.0), lens=None
                 ) -> tuple[ArmView | SkippedPhoto, dict]:
    """One photo's corners (sub-pixel) as an :class:`ArmView` (or a falsy
    :class:`SkippedPhoto` with the reason), and its ``images[]`` entry (``size_px`` of the
    photo); ``size``: the declared camera's, or None; ``lens``: its ``(K, dist)`` when
    declared (the corners are then found in its ideal pixels)."""
    try:
        bgr, _, _ = load_photo(folder, image, size)
    except PhotoRefused as e:
        return _skipped(image, e.reason)
    if bgr is None:
        return _skipped(image, "not a readable image")
    gray = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
    det = find_sheet_markers(gray, sheet)
    if det.reason:
        return _skipped(image, det.reason)
    edges = edge_points(gray, det.corners_px, geometry=marker_geometry(sheet))
    K, dist = lens if lens is not None else (None, None)
    corners = corners_in_lens(edges, det.corners_px, K, dist)
    view = ArmView(image, np.asarray(q, float), float(j4),
                   np.asarray(det.corners_mm, float).reshape(-1, 2),
                   np.asarray(corners, float).reshape(-1, 2), tuple(approach),
                   np.asarray(edges, float), np.asarray(det.corners_px, float).reshape(-1, 4, 2))
    return view, {"file": image, "status": "ok", "n_markers": int(len(det.ids)),
                  "size_px": [int(gray.shape[1]), int(gray.shape[0])]}


def _measure_one(a):
    *args, lens = a
    return measure_view(*args, lens=lens)


def calibrate_arm_camera(folder, *, progress: bool = False, jobs: int = 1) -> dict:
    """calibration.json (as a dict) of an arm-camera dataset: the robot's base parameters
    with std and covariance, and the ``cameras`` entry with ``T_flange_camera``.
    ``progress``: a bar (or one line per stage) while the photos are measured; ``jobs``:
    processes measuring them (each photo's result is the same for any number)."""
    folder, sheet, nominal, camera, mount, poses, rep = read_arm_session(folder)
    views, images = [], []
    size0 = None if camera is None else camera[0]
    lens0 = None if camera is None else camera[1:]
    args = [(folder, sheet, size0, img, q, j4, sg, lens0) for img, q, j4, sg in poses]
    pbar = bar(progress, total=len(poses), desc="measure arm photos", unit="photo",
               note=f"{jobs} job(s)")
    pool = None
    try:
        if jobs > 1 and len(args) > 1:
            pool = ProcessPoolExecutor(max_workers=min(jobs, len(args)),
                                       initializer=exit_with_parent, initargs=(os.getpid(),))
            results = pool.map(_measure_one, args, chunksize=1)
        else:
            results = map(_measure_one, args)
        for v, entry in results:
            images.append(entry)
            pbar.update()
            if v:   # a SkippedPhoto is falsy: its entry says why
                views.append(v)
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
        pbar.close()
    sizes = {tuple(e["size_px"]) for e in images if e["status"] == "ok"}
    if camera is None and len(sizes) > 1:
        raise CalibrationError(f"photos of {len(sizes)} sizes ({', '.join(f'{a}x{b}' for a, b in sorted(sizes))}) "
                               "and no camera declared: one camera takes photos of one size",
                               file=str(folder / "session.json"), field="camera")
    if len(views) < MIN_POSES:
        why = {}
        for e in images:
            if e["status"] != "ok":
                why.setdefault(e.get("reason") or "unknown", []).append(e["file"])
        common = sorted(why.items(), key=lambda kv: -len(kv[1]))[:2]
        said = "; ".join(f"{len(fs)} skipped: {r} ({fs[0]}{', ...' if len(fs) > 1 else ''})"
                         for r, fs in common)
        raise CalibrationError(f"{len(views)} of {len(poses)} photos usable: at least "
                               f"{MIN_POSES} are needed" + (f" ({said})" if said else ""),
                               file=str(folder / "session.json"))
    lens_reason = []
    check = None
    if camera is None:
        size = sizes.pop()
        lens = estimate_lens(views, size)
        views, dropped = without_misdetected(views, lens.K, lens.dist)
        if np.any(lens.dist) or dropped:  # the corners again in its ideal pixels
            views = [in_lens(v, lens.K, lens.dist) for v in views]
            lens = estimate_lens(views, size)
        K, dist, how, f_sd = lens.K, lens.dist, lens.intrinsics, lens.f_px_std
        if lens.reason:
            lens_reason = [("check", lens.reason)]
    else:
        (size, K, dist), how, f_sd = camera, "declared", 0.0
        views, dropped = without_misdetected(views, K, dist)
        # the declared lens against the views' own: a focal length or a distortion they
        # contradict is named; the floor is the corners' noise with the views' lens
        check = check_declared_lens(views, size, K, dist)
        lens_reason = list(check.reasons)
    # an estimated lens's covariance (f, k1, k2) carried into the fit's: the focal
    # length's error moves the camera's height with it (f / height is what the views fix)
    fit = fit_arm_camera(views, K, dist, nominal,
                         corner_sigma_px=None if check is None else check.corner_sigma_px,
                         lens_cov=None if camera is not None else lens.cov)
    if how == "estimated":
        lens_reason += lens_height_reason(fit, K)
    d = fit.to_json()
    for entry, v, rms in zip([e for e in images if e["status"] == "ok"], views, fit.view_rms_px):
        entry["corner_rms_px"] = float(rms)
        if v.file in dropped:   # markers found pixels off its own pose fit: left out
            entry["markers_left_out"] = dropped[v.file]
    cam = {"images": [v.file for v in views], "size_px": list(size), "K": K.tolist(),
           "dist": dist.tolist(), "T_flange_camera": d["T_flange_camera"],
           "mount": mount, "T_flange_camera_std": d["T_flange_camera_std"],
           "corner_rms_px": d["corner_rms_px"], "n_corners": d["n_corners"],
           "corner_sigma_px": fit.corner_sigma_px, "intrinsics": how}
    if how != "declared":
        cam["f_px_std"] = f_sd if np.isfinite(f_sd) else None
    if check is not None:
        cam["lens_check"] = check.to_json()
    doc = CalibrationResult(
        method="arm_camera", params=d["params"], std=d["std"], covariance=d["covariance"],
        nominal=nominal.to_json(), effects=tuple(d["effects"]), cameras=[cam],
        identifiability=d["identifiability"], images=tuple(images),
        notes=("robot calibrated from the arm camera's views of the marker field (no pen): "
               "the base model, and the backlash of a joint reached from both sides; other "
               "joint effects are not looked for in this version",),
        extra={"not_identifiable": d["not_identifiable"], "pose_rms": d["pose_rms"],
               "poses": _pose_table(views, fit)})
    return _judged(doc, fit, views, rep,
                   undetermined_reasons(fit, mount, undetermined=(how == UNDETERMINED))
                   + lens_reason)


def _judged(doc: CalibrationResult, fit, views, rep, reasons) -> dict:
    """calibration.json with ``valid_for`` (what the poses covered; the one owner:
    ``dataset/valid_for``) and the verdict judged against it as the pen's is: a joint
    reached from one side only leaves its backlash unidentified, never "ready"."""
    valid_for = valid_for_block(doc.to_json())
    verdict = judge_camera_poses(
        fit.flange_residual_mm, fit.flange_sigma_mm, fit.flange_heldout_mm,
        n_params=fit.n_params_xy, repeatability_mm=rep, reasons=reasons,
        ids=[v.file for v in views], heldout_inflate=fit.flange_heldout_inflate,
        repeat_pairs=repeat_pairs(views), valid_for=valid_for)
    return replace(doc, valid_for=valid_for, verdict=verdict.to_json()).to_json()
