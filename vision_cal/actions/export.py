"""The action of ``vision-cal export``: a calibration as URDF (plus an effects side file) or
YAML."""

from __future__ import annotations

import sys
from dataclasses import dataclass

from vision_cal.actions.console import say, warn

from vision_cal.estimate.plausible import check_units
from vision_cal.camera.export import transform_path, write_opencv, write_ros
from vision_cal.camera.fixed import camera_of
from vision_cal.camera.handeye_locate import flange_camera_of, is_flange_camera
from vision_cal.dataset.calibration import load_calibration_or_camera
from vision_cal.dataset.io import distinct_outputs, written_together
from vision_cal.dataset.out_folder import output_file_of_kind, replacing_files
from vision_cal.dataset.robot import load_robot_file
from vision_cal.dataset.trust import refuse_unreliable
from vision_cal.dataset.valid_for import check as check_valid_for
from vision_cal.dataset.valid_for import enforce as enforce_valid_for
from vision_cal.dataset.valid_for import of as valid_for_of
from vision_cal.errors import VisionCalError
from vision_cal.report.export import effects_path, export


@dataclass(frozen=True)
class ExportRequest:
    """What ``vision-cal export`` was asked (its arguments; see ``vision-cal export --help``)."""

    calibration: str
    quiet: bool = False
    urdf: str | None = None
    yaml: str | None = None
    robot: str | None = None
    force: bool = False
    opencv: str | None = None
    ros: str | None = None
    camera: int = 0


@dataclass(frozen=True)
class ExportOutcome:
    """The files written, in order, and the warnings for the console: the calibration's
    trust (``--force`` over an unreliable one) first, then each extrapolation beyond its
    ``valid_for`` (with ``--force``)."""

    written: tuple[str, ...]
    warnings: tuple[str, ...] = ()
    said: tuple[str, ...] = ()

    def show(self, quiet: bool = False) -> int:
        for w in self.warnings:
            print(w, file=sys.stderr)
        for w in self.said:   # --force: exported beyond what was calibrated
            warn(w)
        if not quiet:
            say(f"wrote {p}" for p in self.written)
        return 0


def export_calibration(req: ExportRequest) -> ExportOutcome:
    """The calibration exported: URDF and its effects, controller YAML, OpenCV and ROS
    camera files, written together or not at all."""
    if not (req.urdf or req.yaml or req.opencv or req.ros):
        raise VisionCalError("nothing to export: give --urdf, --yaml, --opencv and/or --ros")
    for opt, path in (("--urdf", req.urdf), ("--yaml", req.yaml), ("--opencv", req.opencv),
                      ("--ros", req.ros)):
        if path:   # never over a JSON (a calibration), an image or a PDF
            output_file_of_kind(path, "text", field=opt)
    distinct_outputs(_outputs(req),
                     [("CALIBRATION.json", req.calibration), ("--robot", req.robot)])
    # a hand-eye's calibration holds a camera alone (no robot model: issue 40)
    model, doc = load_calibration_or_camera(req.calibration, sheet_frame=False)
    if model is None and (req.urdf or req.yaml or req.robot):
        raise VisionCalError("this calibration holds a camera alone (a hand-eye's): only "
                             "--opencv and --ros apply", file=req.calibration,
                             field="--urdf" if req.urdf else ("--yaml" if req.yaml
                                                             else "--robot"))
    robot = load_robot_file(req.robot) if req.robot else None
    # metres, radians: refused before anything is written (the owner: estimate/plausible)
    if model is not None:
        check_units(model, doc, file=str(req.calibration),
                    nominal=None if robot is None else robot.nominal,
                    nominal_of=f"the robot file {req.robot}")

    warn = refuse_unreliable(doc, req.calibration, force=req.force)
    said = []
    if req.urdf or req.yaml:   # the robot model for every pose: what it could not identify
        outside = check_valid_for(valid_for_of(doc, file=str(req.calibration)),
                                  cal=str(req.calibration), whole_model=True)
        said = enforce_valid_for(outside, file=str(req.calibration), force=req.force,
                                 what="--urdf/--yaml")
    limits, limits4, limits3 = doc.get("joint_limits_deg"), None, None
    if robot is not None:
        limits, limits4 = robot.joint_limits_deg, robot.joint4_limits_deg
        limits3 = robot.joint3_limits_mm
    written = []
    # one output set: an earlier export's files (an effects file this one does not write
    # among them) go to previous/export-<name>/ first
    with replacing_files(_outputs(req), command="export", quiet=req.quiet,
                         inputs=[("CALIBRATION.json", req.calibration), ("--robot", req.robot)]
                         ), written_together():
        if req.opencv or req.ros:   # a still camera, or one on any arm's flange (issue 40)
            cam = (flange_camera_of(doc, req.camera, file=req.calibration)
                   if is_flange_camera(doc, req.camera) else
                   camera_of(doc, req.camera, file=req.calibration))
            written += [write_opencv(req.opencv, cam)] if req.opencv else []
            written += write_ros(req.ros, cam) if req.ros else []
        if req.urdf or req.yaml:
            written = export(doc, urdf=req.urdf, yaml_path=req.yaml,
                             limits_deg=limits, limits4_deg=limits4,
                             limits3_mm=limits3, extrapolated=said) + written
    return ExportOutcome(tuple(str(p) for p in written), (warn,) if warn else (), tuple(said))


def _outputs(req: ExportRequest) -> list:
    """(option, path) of every file the export writes (None: not asked)."""
    return [("--urdf", req.urdf), ("--urdf (its effects)", req.urdf and effects_path(req.urdf)),
            ("--yaml", req.yaml), ("--opencv", req.opencv), ("--ros", req.ros),
            ("--ros (its transform)", req.ros and transform_path(req.ros))]
