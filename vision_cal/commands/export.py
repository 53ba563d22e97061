"""``vision-cal export``: a calibration as URDF (plus an effects side file) or YAML."""

from __future__ import annotations

NAME = "export"
HELP = "export calibration.json as URDF joint origins (+ effects side file) or YAML"
EXAMPLES = """\
examples:
  vision-cal fixtures/paper_sm5 --out /tmp/x
  vision-cal export /tmp/x/calibration.json --urdf /tmp/x/robot.urdf
  vision-cal export /tmp/x/calibration.json --yaml /tmp/x/calibration.yaml
  vision-cal export /tmp/x/calibration.json --opencv camera.yaml --ros camera_info.yaml
"""


def add_arguments(p) -> None:
    p.add_argument("calibration", metavar="CALIBRATION.json", help="the calibration.json to export")
    p.add_argument("--urdf", metavar="ROBOT.urdf", help="URDF with the calibrated joint origins; "
                   "effects go to ROBOT.effects.yaml beside it")
    p.add_argument("--yaml", metavar="FILE.yaml", help="parameters, std and effects as YAML")
    p.add_argument("--robot", metavar="ROBOT.yaml",
                   help="robot file: the URDF's joint limits, joint 3's travel and joint 4's "
                        "range (default: calibration.json's joint_limits_deg, which the "
                        "session's robot file gave; joints 3 and 4: vision_cal.motion's)")
    p.add_argument("--force", action="store_true",
                   help="export even a calibration whose verdict is 'not reliable'")
    p.add_argument("--opencv", metavar="FILE.yaml", help="a still camera as OpenCV FileStorage "
                   "YAML: camera_matrix, distortion_coefficients, T_robot_camera (mm)")
    p.add_argument("--ros", metavar="FILE.yaml", help="a still camera as ROS camera_info YAML, "
                   "and FILE.transform.yaml: robot -> camera optical frame")
    p.add_argument("--camera", type=int, default=0, metavar="N",
                   help="which of calibration.json's cameras (default 0)")


def run(args) -> int:
    from vision_cal.dataset.calibration import load_calibration
    from vision_cal.dataset.io import distinct_outputs, output_file, written_together
    from vision_cal.errors import VisionCalError
    from vision_cal.camera.export import transform_path
    from vision_cal.report.export import effects_path, export

    if not (args.urdf or args.yaml or args.opencv or args.ros):
        raise VisionCalError("nothing to export: give --urdf, --yaml, --opencv and/or --ros")
    for opt, path in (("--urdf", args.urdf), ("--yaml", args.yaml), ("--opencv", args.opencv),
                      ("--ros", args.ros)):
        if path:
            output_file(path, field=opt)
    distinct_outputs([("--urdf", args.urdf),
                      ("--urdf (its effects)", args.urdf and effects_path(args.urdf)),
                      ("--yaml", args.yaml), ("--opencv", args.opencv), ("--ros", args.ros),
                      ("--ros (its transform)",
                       args.ros and transform_path(args.ros))],
                     [("CALIBRATION.json", args.calibration)])
    _, doc = load_calibration(args.calibration)
    from vision_cal.dataset.trust import refuse_unreliable

    warn = refuse_unreliable(doc, args.calibration, force=args.force)
    if warn:
        import sys

        print(warn, file=sys.stderr)
    limits, limits4, limits3 = doc.get("joint_limits_deg"), None, None
    if args.robot:
        from vision_cal.dataset.robot import load_robot_file

        robot = load_robot_file(args.robot)
        limits, limits4 = robot.joint_limits_deg, robot.joint4_limits_deg
        limits3 = robot.joint3_limits_mm
    written = []
    with written_together():
        if args.opencv or args.ros:
            from vision_cal.camera.export import write_opencv, write_ros
            from vision_cal.camera.fixed import camera_of

            cam = camera_of(doc, args.camera, file=args.calibration)
            written += [write_opencv(args.opencv, cam)] if args.opencv else []
            written += write_ros(args.ros, cam) if args.ros else []
        if args.urdf or args.yaml:
            written = export(doc, urdf=args.urdf, yaml_path=args.yaml,
                             limits_deg=limits, limits4_deg=limits4,
                             limits3_mm=limits3) + written
    for path in written:
        if not args.quiet:
            print(f"wrote {path}")
    return 0
