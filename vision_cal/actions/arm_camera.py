"""A dataset of photos taken by the arm's camera: session.json ``poses``, measured and fitted.

    doc = calibrate_arm_camera("arm/", cache_dir="out/.cache")    # calibration.json's dict

session.json (``docs/format.md``, "Cameras")::

    "camera": {"size_px": [w, h], "K": [[...]], "dist": [...]},     optional: declared lens
    "camera_mount": "flange",           "flange" (turns with joint 4) or "link2"
    "poses": [ {"image": "pose_000.png", "joints_deg": [q1, q2], "j4_deg": 30.0} ]

with the contract's ``sheet`` (the marker field, ``vision-cal sheet --field``) and
``robot`` blocks; read by :func:`vision_cal.dataset.session.load_arm_session`. The photos go
through the measurement every photo goes through (:func:`measure_arm_photos`): listed and
checked before anything is decoded (``measure/listing.py``), their markers detected in
parallel and cached by content (``measure/detect.py``, the markers only), a photo that
cannot be used skipped with the same reason as anywhere else; then the corners in the lens
(``camera/arm.lens_corners``) and the fit (``camera/arm.py``).

``vision-cal handeye FOLDER`` (:func:`calibrate_arm`, first: its request, its run, its
outcome that prints itself) writes calibration.json into an output folder that is never the
photos' (the detections cached in its ``.cache``). (``handeye --poses`` is
:func:`vision_cal.actions.handeye.handeye_pairs`.)
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from vision_cal.actions.console import say, verdict_and_written
from vision_cal.camera.arm import (MIN_POSES, ArmView, check_declared_lens, estimate_lens,
                                   fit_arm_camera, lens_corners, without_misdetected)
from vision_cal.camera.fixed import UNDETERMINED
from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.dataset.fields import FieldReader
from vision_cal.dataset.out_folder import writing_into
from vision_cal.dataset.session import Session, load_arm_session
from vision_cal.dataset.valid_for import build as valid_for_block
from vision_cal.errors import CalibrationError, VisionCalError
from vision_cal.estimate.plausible import RADIAN_RANGE, radians_given
from vision_cal.estimate.verdict import judge_camera_poses
from vision_cal.measure.cache import DetectionCache
from vision_cal.measure.detect import detect_all
from vision_cal.measure.listing import photos_to_measure


@dataclass(frozen=True)
class ArmCameraRequest:
    """What ``vision-cal handeye FOLDER`` was asked (see its ``--help``)."""

    folder: str
    out: str
    jobs: int | None = None       # photo measurement processes (default: every core)
    quiet: bool = False


@dataclass(frozen=True)
class ArmCameraOutcome:
    """calibration.json as written (a dict, docs/format.md "Cameras") and its path."""

    calibration: dict
    path: Path

    def lines(self) -> list[str]:
        """``vision-cal handeye FOLDER``: the photos used, the arm, the camera's mount, the
        effects and the verdict."""
        doc = self.calibration
        cam = doc["cameras"][0]
        p, sd = doc["params"], doc["std"]
        skipped = [im for im in doc["images"] if im["status"] != "ok"]
        lines = [f"{len(cam['images'])} photos used, {len(skipped)} skipped; corner RMS "
                 f"{cam['corner_rms_px']:.3f} px",
                 f"L1 {p['L1_mm']:.4f} +- {sd['L1_mm']:.4f} mm, L2 {p['L2_mm']:.4f} +- "
                 f"{sd['L2_mm']:.4f} mm, zeros {p['joint_zero_deg'][0]:.4f} "
                 f"{p['joint_zero_deg'][1]:.4f} deg, base {p['base_mm'][0]:.3f} "
                 f"{p['base_mm'][1]:.3f} mm",
                 flange_camera_line(cam)]
        lines += [f"joint {e['joint']} backlash {e['deg']:.4f} +- {e['std']:.4f} deg"
                  for e in doc["effects"]]
        return lines + verdict_and_written(doc["verdict"], self.path)

    def show(self, quiet: bool = False) -> int:
        if not quiet:
            say(self.lines())
        return 0


def flange_camera_line(cam: dict) -> str:
    """T_flange_camera in words, with units: the camera's x and y in the flange frame with
    their std; its z is the height above the sheet's plane (SCARA motion is planar: the
    flange's own height, hence the camera's height above the flange, is not identifiable)."""
    t = cam["T_flange_camera"]
    sd = cam["T_flange_camera_std"]["translation_mm"]
    return (f"T_flange_camera: camera at x {t[0][3]:.3f} +- {sd[0]:.3f} mm, y {t[1][3]:.3f} +- "
            f"{sd[1]:.3f} mm in the flange frame; its height above the flange is not "
            f"identifiable (planar motion): z {t[2][3]:.3f} mm is its height above the "
            "sheet's plane")


def calibrate_arm(req: ArmCameraRequest) -> ArmCameraOutcome:
    """Calibrate the robot and T_flange_camera from the photos of ``req.folder``."""
    if req.jobs is not None and req.jobs < 1:
        raise VisionCalError(f"must be at least 1, got {req.jobs}", field="--jobs")
    # the output folder: never the photos' folder; an earlier run's results (this command's
    # or a pen calibration's) go to previous/ first; locked while written (issue 30)
    with writing_into(req.out, command="handeye", inputs=[("FOLDER", req.folder)],
                      quiet=req.quiet) as out:
        doc = calibrate_arm_camera(req.folder, cache_dir=out / ".cache", progress=not req.quiet,
                                   jobs=req.jobs or os.cpu_count() or 1)
        path = CalibrationResult.from_json(doc).write(out / "calibration.json")
    return ArmCameraOutcome(doc, path)


log = logging.getLogger(__name__)


def measure_arm_photos(session: Session, *, cache_dir, jobs: int | None = 1, progress=False,
                       config: EstimatorConfig | None = None
                       ) -> tuple[list[ArmView], list[dict]]:
    """The arm camera's photos measured as every photo is.

        views, images = measure_arm_photos(load_arm_session("arm/"), cache_dir="out/.cache")

    The listing and its checks (:func:`vision_cal.measure.listing.photos_to_measure`),
    stage 1 on the markers only, cached in ``cache_dir`` and run in ``jobs`` processes
    (:func:`vision_cal.measure.detect.detect_all`), each photo's corners in the declared
    lens (:func:`vision_cal.camera.arm.lens_corners`). Returns the views of the photos
    measured, in the poses' order, and every photo's ``images[]`` entry (``ok`` with its
    markers and size, or ``skipped`` with the measurement's reason)."""
    items, warnings, _ = photos_to_measure(session)
    warnings += detect_all(items, session, DetectionCache(Path(cache_dir)), jobs=jobs,
                           progress=progress, config=config or DEFAULT, dots=False)
    for w in warnings:
        log.warning(w)
    cam = session.camera
    lens = (None, None) if cam is None else (cam.K, cam.dist)
    views, images = [], []
    for ph, pose in zip(items, session.poses):
        d = ph.det
        if d.status != "ok":
            images.append({"file": pose.image, "status": "skipped", "reason": d.reason})
            continue
        views.append(ArmView(pose.image, np.asarray(pose.joints_deg, float), pose.j4_deg,
                             np.asarray(d.corners_mm, float).reshape(-1, 2),
                             lens_corners(d, *lens), pose.approach, d))
        images.append({"file": pose.image, "status": "ok", "n_markers": int(len(d.marker_ids)),
                       "size_px": [int(d.size_px[0]), int(d.size_px[1])]})
    return views, images


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


def calibrate_arm_camera(folder, *, cache_dir, progress: bool = False, jobs: int = 1) -> dict:
    """calibration.json (as a dict) of an arm-camera dataset.

        doc = calibrate_arm_camera("arm/", cache_dir="out/.cache", jobs=4)

    The robot's base parameters with std and covariance, and the ``cameras`` entry with
    ``T_flange_camera``. ``cache_dir``: the detections' cache (the output folder's
    ``.cache``); ``progress``: a bar (or one line per stage) while the photos are
    measured; ``jobs``: processes measuring them (each photo's result is the same for any
    number)."""
    session = load_arm_session(folder)
    folder, mount, camera = Path(session.root), session.camera_mount, session.camera
    if radians_given([p.joints_deg for p in session.poses]):
        FieldReader(str(session.path)).fail(
            "poses", f"every joint angle is within +-{RADIAN_RANGE:.2f}: written in radians? "
                     "joints_deg are degrees (multiply by 57.2958)")
    nominal, rep = session.robot.params, session.robot.repeatability_mm
    poses = session.poses
    views, images = measure_arm_photos(session, cache_dir=cache_dir, jobs=jobs,
                                       progress=progress)
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
            views = [v.in_lens(lens.K, lens.dist) for v in views]
            lens = estimate_lens(views, size)
        K, dist, how, f_sd = lens.K, lens.dist, lens.intrinsics, lens.f_px_std
        if lens.reason:
            lens_reason = [("check", lens.reason)]
    else:
        (size, K, dist), how, f_sd = (camera.size_px, camera.K, camera.dist), "declared", 0.0
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
