"""The hand-eye from pose pairs (``vision-cal handeye --poses FILE``): the file read
(:mod:`vision_cal.camera.poses_file`), the fit (:mod:`vision_cal.camera.pose_pairs`), the
contract's verdict (:func:`vision_cal.estimate.verdict.judge_camera_poses`, each pair's
target position standing for a mark) and calibration.json (docs/format.md, "Hand-eye from
pose pairs"). Returns what was found, which prints itself.

Also the hand-eye of any arm from photos and the robot's poses (``vision-cal handeye
PHOTOS/ --robot-poses POSES``, :func:`handeye_photos`, at the end)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vision_cal.actions.console import say, verdict_and_written
from vision_cal.camera.pose_pairs import LABELS, PairsFit, fit_pose_pairs
from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.dataset.out_folder import writing_into
from vision_cal.camera.poses_file import read_poses
from vision_cal.estimate.verdict import Verdict, judge_camera_poses
from vision_cal.errors import CalibrationError
# the photos-and-poses path (issue 40)
from vision_cal.camera.board import find_board, load_board
from vision_cal.camera.handeye import HandeyeFit, estimated_lens_fit, fit_handeye
from vision_cal.camera.handeye_document import photos_document
from vision_cal.camera.handeye_lsq import View
from vision_cal.camera.handeye_verdict import judge_handeye, lens_check, limited_by
from vision_cal.camera.robot_poses import pair_with_photos, read_robot_poses
from vision_cal.dataset.camera_block import read_lens
from vision_cal.dataset.fields import FieldReader
from vision_cal.dataset.io import read_json
from vision_cal.dataset.photos import PhotoRefused, list_photos, load_photo
from vision_cal.errors import VisionCalError

#: what X and Y are, by mount (the contract's names)
NAMES = {"arm": ("T_flange_camera", "T_robot_target", "robot"),
         "fixed": ("T_robot_camera", "T_flange_target", "flange")}


@dataclass(frozen=True)
class HandeyePairsOutcome:
    """The fit of the pose pairs, the calibration.json written from it, and where."""

    fit: PairsFit
    document: dict
    path: Path

    @property
    def camera_name(self) -> str:
        """What the fitted X is called (the mount's name of the camera's pose)."""
        return NAMES[self.fit.mount][0]

    def lines(self) -> list[str]:
        """``vision-cal handeye --poses``: the pairs, the camera's pose with its std, the
        pairs left out, and the verdict."""
        fit, xname = self.fit, self.camera_name
        t, sd = fit.X[:3, 3], self.document["cameras"][0][f"{xname}_std"]["translation_mm"]
        lines = [(f"{len(fit.ids) + len(fit.repeats)} pairs at {len(fit.ids)} distinct flange "
                  "poses (a repeated pose counted once), " if fit.repeats else
                  f"{len(fit.ids)} pairs, ") + f"{len(fit.outliers)} left out; pair scatter "
                 f"{fit.sigma_mm:.3f} mm, {fit.sigma_deg:.3f} deg (one std per axis)",
                 f"{xname}: at {t[0]:.3f} {t[1]:.3f} {t[2]:.3f} mm (std "
                 + ", ".join("not identifiable" if v is None else f"{v:.3f}" for v in sd) + ")"]
        lines += [f"left out: {r}" for r in fit.outlier_reasons]
        return lines + verdict_and_written(self.document["verdict"], self.path)

    def show(self, quiet: bool = False) -> int:
        if not quiet:
            say(self.lines())
        return 0


@dataclass(frozen=True)
class HandeyeRequest:
    """What ``vision-cal handeye --poses`` was asked (see its ``--help``)."""

    poses: str
    out: str
    units: str | None = None       # mm | m (None: the file's, else mm)
    mount: str | None = None       # arm | fixed (None: the file's, else arm)
    z_mm: float | None = None      # the target origin's height (None: the file's or unknown)
    quiet: bool = False


def _pair_reasons(fit: PairsFit, xname: str, yframe: str) -> list[tuple[str, str]]:
    """The verdict's (status, sentence) of a pairs fit: its checks' findings first (a wrong
    unit or reading leaves every std meaningless: then nothing that follows from it), the
    unseen height, the directions no pair sees, stds too large, the pairs left out."""
    reasons: list[tuple[str, str]] = list(fit.findings)
    wrong = any(st == "not reliable" for st, _ in fit.findings)
    if not fit.z_given:
        reasons.append(("check", f"the camera's height ({xname} z) is not identifiable from a "
                                 "SCARA's poses: taken with the target's origin at z = 0 in "
                                 f"the {yframe} frame; give its height with --z-mm (or "
                                 "target_z_mm in the file)"))
    for sentence in dict.fromkeys(d["reason"] for d in fit.not_identifiable
                                  if d["label"] in fit.unseen and not wrong):
        reasons.append(("not reliable", sentence))
    others = [d for d in fit.not_identifiable
              if d["label"] != "X_z_mm" and d["label"] not in fit.unseen]
    if others and not wrong:
        reasons.append(("not reliable", "the pairs do not determine "
                        + ", ".join(d["label"] for d in others)
                        + ": turn the flange more between pairs, over more places"))
    for r in fit.outlier_reasons:
        if r.startswith("more pairs disagree") and not fit.findings:
            reasons.append(("not reliable", r))
    if fit.outliers:
        reasons.append(("check", f"{len(fit.outliers)} pair(s) left out as disagreeing with "
                                 "the others beyond their scatter: " + ", ".join(fit.outliers)))
    return reasons


def _pair_table(fit: PairsFit) -> list[dict]:
    """calibration.json ``pairs``: every pair, its status (``ok``, ``outlier`` with the
    reason, ``repeat`` of an earlier pair's pose) and residuals."""
    why_out = {r.split(":")[0].removeprefix("pair "): r for r in fit.outlier_reasons}
    table = []
    for i, pid in enumerate(fit.ids):
        ok = bool(fit.inlier[i])
        row = {"id": pid, "status": "ok" if ok else "outlier",
               "residual_mm": float(np.linalg.norm(fit.residual_mm[i])),
               "residual_deg": float(np.linalg.norm(fit.residual_deg[i])),
               "residual_xyz_mm": [float(v) for v in fit.residual_mm[i]],
               "heldout_xyz_mm": [float(v) for v in fit.heldout_mm[i]],
               "sigma_xy_mm": float(fit.sigma_xy_mm[i])}
        if not ok:
            row["reason"] = why_out.get(pid, "left out")
        table.append(row)
    for k, (pid, first) in enumerate(fit.repeats):
        table.append({"id": pid, "status": "repeat", "repeat_of": first,
                      "residual_mm": float(np.linalg.norm(fit.repeat_residual_mm[k])),
                      "residual_deg": float(np.linalg.norm(fit.repeat_residual_deg[k])),
                      "residual_xyz_mm": [float(v) for v in fit.repeat_residual_mm[k]]})
    return table


def pairs_document(fit: PairsFit, *, source: str, units: str,
                   config: EstimatorConfig | None = None) -> dict:
    """calibration.json (as a dict) of a hand-eye from pose pairs."""
    config = config or DEFAULT
    xname, yname, yframe = NAMES[fit.mount]
    std = fit.std()
    inl = fit.inlier
    ids = [i for i, ok in zip(fit.ids, inl) if ok]
    verdict = judge_camera_poses(
        fit.residual_mm[inl, :2], fit.sigma_xy_mm[inl], fit.heldout_mm[inl, :2],
        n_params=fit.n_params_xy, reasons=_pair_reasons(fit, xname, yframe),
        config=config.verdict, ids=ids,
        # the pairs' scatter holds the robot's repeatability already: not added twice
        repeatability_mm=0.0)
    z_from = ("given" if fit.z_given else
              "assumed: the target's origin at z = 0 (not identifiable)")
    cam = {"mount": fit.mount, "pairs": ids,
           xname: fit.X.tolist(), f"{xname}_std": std["X"],
           yname: fit.Y.tolist(), f"{yname}_std": std["Y"],
           "target_z_mm": fit.z_mm, "target_z_from": z_from}
    inl_mm = fit.residual_mm[inl]
    inl_deg = fit.residual_deg[inl]
    return CalibrationResult(
        method="pose_pairs", cameras=[cam], outliers=tuple(fit.outliers),
        covariance={"params": list(LABELS), "matrix": fit.cov.tolist()},
        initial_guess={"method": "4-DOF closed form (SCARA: rotations about z)",
                       xname: fit.start_X.tolist(), yname: fit.start_Y.tolist()},
        verdict=verdict.to_json(), config=config.to_json(),
        notes=(f"{xname} from {len(ids)} pose pairs ({len(fit.outliers)} left out); the "
               "floor is the pairs' own scatter (their 6x6 covariance in the camera "
               "frame, the robot's repeatability included): the verdict tests the "
               "held-out pairs and the largest error against it, not against a stated "
               "noise",),
        extra={
            "poses_file": source, "units_read": units, "mount": fit.mount,
            "not_identifiable": list(fit.not_identifiable), "pairs": _pair_table(fit),
            "pair_rms": {"residual_mm": float(np.sqrt(np.mean(np.sum(inl_mm**2, axis=1)))),
                         "residual_deg": float(np.sqrt(np.mean(np.sum(inl_deg**2, axis=1))))},
            "pair_scatter": {"sigma_mm": fit.sigma_mm, "sigma_deg": fit.sigma_deg,
                             "labels": ["x_mm", "y_mm", "z_mm", "rot_x_deg", "rot_y_deg",
                                        "rot_z_deg"],
                             "covariance_camera": fit.noise_cov.tolist()},
            "pair_checks": {
                "pairs": len(fit.ids) + len(fit.repeats), "distinct_poses": len(fit.ids),
                "repeats": len(fit.repeats),
                "unit_scale": fit.scale if np.isfinite(fit.scale) else None,
                "unit_scale_std": fit.scale_std if np.isfinite(fit.scale_std) else None,
                "unseen": list(fit.unseen),
                "findings": [{"status": st, "reason": t} for st, t in fit.findings]}}
    ).to_json()


def handeye_pairs(req: HandeyeRequest) -> HandeyePairsOutcome:
    """Read, fit, judge and write ``OUT/calibration.json``."""
    pf = read_poses(req.poses, units=req.units, mount=req.mount, target_z_mm=req.z_mm)
    fit = fit_pose_pairs(list(pf.pairs), pf.mount, z_mm=pf.target_z_mm,
                         config=DEFAULT.handeye, progress=not req.quiet)
    if not fit:
        raise CalibrationError(fit.reason, file=str(pf.path))
    doc = pairs_document(fit, source=str(pf.path), units=pf.units)
    # the output folder's one owner (issue 30): never the folder holding the pairs file; an
    # earlier run's results go to previous/; locked while written
    with writing_into(req.out, command="handeye", inputs=[("--poses", req.poses)],
                      quiet=req.quiet) as out:
        path = CalibrationResult.from_json(doc).write(out / "calibration.json")
    return HandeyePairsOutcome(fit, doc, path)


# --------------------------------------------------------------------------- photos and poses
# ``vision-cal handeye PHOTOS/ --robot-poses POSES --sheet BOARD --mount fixed|arm``: any
# arm (issue 40), the photos' board and the robot's flange poses (docs/format.md, "Photos
# and the robot's poses"); the fit is :mod:`vision_cal.camera.handeye`, its verdict
# :mod:`vision_cal.camera.handeye_verdict`.


@dataclass(frozen=True)
class HandeyePhotosRequest:
    """What ``vision-cal handeye PHOTOS/ --robot-poses`` was asked (see its ``--help``)."""

    folder: str
    robot_poses: str
    sheet: str
    mount: str
    out: str
    camera: str | None = None      # a JSON with the lens (``camera`` block); None: estimated
    quiet: bool = False


@dataclass(frozen=True)
class HandeyePhotosOutcome:
    """The fit, the calibration.json written from it, and where."""

    fit: HandeyeFit
    document: dict
    path: Path
    skipped: tuple[tuple[str, str], ...]

    def lines(self) -> list[str]:
        """``vision-cal handeye PHOTOS/ --robot-poses``: the photos, the two transforms with
        their std, each photo predicted from the others, what limits it, and the verdict."""
        doc, fit = self.document, self.fit
        he = doc["handeye"]
        cam = doc["cameras"][0]
        lines = [f"{len(fit.views)} photos used, {len(fit.left_out)} left out, "
                 f"{len(self.skipped)} skipped; board: {he['board']['describes']}; lens "
                 f"{cam['intrinsics']}"]
        for name, T, sd in ((fit.names[0], cam[fit.names[0]], cam[f"{fit.names[0]}_std"]),
                            (fit.names[1], doc[fit.names[1]], doc[f"{fit.names[1]}_std"])):
            t = T[0][3], T[1][3], T[2][3]
            lines.append(f"{name}: at {t[0]:.2f} {t[1]:.2f} {t[2]:.2f} mm (std "
                         + " ".join(f"{v:.2f}" for v in sd["translation_mm"]) + " mm, "
                         + " ".join(f"{v:.3f}" for v in sd["rotation_deg"]) + " deg)")
        for im in doc["images"]:
            if im["status"] == "ok":
                lines.append(f"  {im['file']}: residual {im['residual_px']:.2f} px; predicted "
                             f"from the others {im['heldout_px']:.2f} px ({im['heldout_mm']:.2f}"
                             f" mm at the board), stated {im['stated_px']:.2f} px")
            else:
                lines.append(f"  {im['file']}: {im['status']}: {im['reason']}")
        h = he["heldout"]
        lines.append(f"held-out photos: {h['rms_px']:.2f} px RMS ({h['rms_mm']:.2f} mm at the "
                     f"board), stated {h['stated_px']:.2f} px ({h['stated_mm']:.2f} mm)")
        lines.append(f"limited by: {he['limited_by']}")
        return lines + [Verdict.from_json(doc["verdict"]).text, f"wrote {self.path}"]

    def show(self, quiet: bool = False) -> int:
        if not quiet:
            say(self.lines())
        return 0


def declared_lens(req: HandeyePhotosRequest):
    """(size_px, K, dist) of ``--camera`` (a JSON holding a ``camera`` block, as in
    session.json, or the block itself), or of PHOTOS/session.json's ``camera``; None."""
    path = Path(req.camera) if req.camera else Path(req.folder) / "session.json"
    if not req.camera and not path.is_file():
        return None
    doc = read_json(path, what="camera (lens)")
    block = doc.get("camera", doc) if isinstance(doc, dict) else doc
    if not req.camera and "camera" not in doc:
        return None
    size, K, dist = read_lens(FieldReader(str(path)), block,
                              "camera" if isinstance(doc, dict) and "camera" in doc else "")
    if len(dist) > 5 and np.any(np.asarray(dist[5:]) != 0):
        raise VisionCalError("only the 5-term lens (k1 k2 p1 p2 k3) is read here",
                             file=str(path), field="camera.dist")
    return size, K, dist


def _detect(req: HandeyePhotosRequest, board, photos, poses, lens_size):
    """Each photo's board points; photos that cannot be used with their reason."""
    views, alts, skipped, size = [], {"quaternion read as qw qx qy qz": [],
                                      "T_flange_robot (the poses inverted)": []}, [], None
    for name, pose in zip(photos, poses):
        try:
            bgr, header, _ = load_photo(req.folder, name, lens_size)
        except PhotoRefused as e:
            skipped.append((name, e.reason))
            continue
        if bgr is None:
            skipped.append((name, "not decoded"))
            continue
        wh = (bgr.shape[1], bgr.shape[0])
        if size is not None and wh != size:
            raise VisionCalError(f"{wh[0]}x{wh[1]} px, the photos before it {size[0]}x{size[1]}"
                                 ": one camera, one size", file=str(Path(req.folder) / name))
        size = wh
        pts = find_board(bgr, board, min_points=DEFAULT.handeye_photos.min_points)
        if pts.reason:
            skipped.append((name, pts.reason))
            continue
        views.append(View(name, pose.T, pts.ids, pts.board_mm, pts.px, pose.joints_deg))
        alts["quaternion read as qw qx qy qz"].append(pose.T_read_as("wxyz"))
        alts["T_flange_robot (the poses inverted)"].append(pose.T_read_as("inverse"))
    return views, alts, skipped, size


def handeye_photos(req: HandeyePhotosRequest) -> HandeyePhotosOutcome:
    """Read the board, the poses and the photos; fit, judge and write OUT/calibration.json."""
    board = load_board(req.sheet)
    folder = Path(req.folder)
    if not folder.is_dir():
        raise VisionCalError("not a folder of photos", file=str(folder))
    photos = list_photos(folder)
    if not photos:
        raise VisionCalError("no photos (png, jpg, ...) in this folder", file=str(folder))
    poses, units = read_robot_poses(req.robot_poses)
    poses = pair_with_photos(poses, photos, req.robot_poses)
    lens = declared_lens(req)
    views, alts, skipped, size = _detect(req, board, photos, poses,
                                         None if lens is None else lens[0])
    if size is None or not views:
        raise CalibrationError("no photo shows the board: " + "; ".join(
            f"{n}: {r}" for n, r in skipped[:4]), file=str(folder))
    if lens is not None and tuple(lens[0]) != tuple(size):
        raise VisionCalError(f"the declared lens is for {lens[0][0]}x{lens[0][1]} px photos, "
                             f"these are {size[0]}x{size[1]}", file=req.camera,
                             field="camera.size_px")
    fit = fit_handeye(views, req.mount, size, lens=None if lens is None else lens[1:],
                      alternatives=alts, source=req.robot_poses, units=units)
    free = (estimated_lens_fit(views, fit, alternatives=alts, source=req.robot_poses,
                               units=units) if lens is not None else None)
    verdict = judge_handeye(fit, lens_check=lens_check(fit, free))
    doc = photos_document(fit, verdict, board=board, req=req, units=units,
                          skipped=skipped, limit=limited_by(fit, DEFAULT.handeye_photos))
    with writing_into(req.out, command="handeye",
                      inputs=[("PHOTOS", req.folder), ("--robot-poses", req.robot_poses)],
                      quiet=req.quiet) as out:
        path = CalibrationResult.from_json(doc).write(out / "calibration.json")
    return HandeyePhotosOutcome(fit, doc, path, tuple(skipped))
