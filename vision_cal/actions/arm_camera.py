"""The arm's camera calibrates the robot and finds its mount (``vision-cal handeye FOLDER``):
the photos measured and fitted (:func:`vision_cal.workflows.arm_session.calibrate_arm_camera`;
the detections cached in the output folder's ``.cache`` as a pen calibration's are),
calibration.json written into an output folder that is never the photos'. Returns what was
found; :mod:`vision_cal.actions.console` prints it. (``handeye --poses`` is
:func:`vision_cal.actions.handeye.handeye_pairs`.)"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from vision_cal.workflows.arm_session import calibrate_arm_camera
from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.dataset.out_folder import writing_into
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
