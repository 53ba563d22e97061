"""The arm's camera calibrates the robot and finds its mount (``vision-cal handeye FOLDER``):
the photos measured and fitted (:func:`vision_cal.workflows.arm_session.calibrate_arm_camera`;
the detections cached in the output folder's ``.cache`` as a pen calibration's are),
calibration.json written into an output folder that is never the photos'. Returns what was
found, which prints itself. (``handeye --poses`` is
:func:`vision_cal.actions.handeye.handeye_pairs`.)"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from vision_cal.actions.console import say, verdict_lines
from vision_cal.workflows.arm_session import calibrate_arm_camera
from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.dataset.out_folder import writing_into
from vision_cal.estimate.verdict import Verdict
from vision_cal.errors import VisionCalError


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
        v = Verdict.from_json(doc["verdict"])
        if v.floor_line:
            lines.append(v.floor_line)
        return lines + verdict_lines(v) + [f"wrote {self.path}"]

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
