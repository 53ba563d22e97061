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
    p.add_argument("calibration", metavar="CALIBRATION.json")
    p.add_argument("--urdf", metavar="ROBOT.urdf", help="URDF with the calibrated joint origins; "
                   "effects go to ROBOT.effects.yaml beside it")
    p.add_argument("--yaml", metavar="FILE.yaml", help="parameters, std and effects as YAML")
    p.add_argument("--opencv", metavar="FILE.yaml", help="a still camera as OpenCV FileStorage "
                   "YAML: camera_matrix, distortion_coefficients, T_robot_camera (mm)")
    p.add_argument("--ros", metavar="FILE.yaml", help="a still camera as ROS camera_info YAML, "
                   "and FILE.transform.yaml: robot -> camera optical frame")
    p.add_argument("--camera", type=int, default=0, metavar="N",
                   help="which of calibration.json's cameras (default 0)")


def run(args) -> int:
    from vision_cal.dataset.calibration import load_calibration
    from vision_cal.dataset.io import output_file
    from vision_cal.errors import VisionCalError
    from vision_cal.report.export import export

    if not (args.urdf or args.yaml or args.opencv or args.ros):
        raise VisionCalError("nothing to export: give --urdf, --yaml, --opencv and/or --ros")
    for opt, path in (("--urdf", args.urdf), ("--yaml", args.yaml), ("--opencv", args.opencv),
                      ("--ros", args.ros)):
        if path:
            output_file(path, field=opt)
    _, doc = load_calibration(args.calibration)
    written = []
    if args.opencv or args.ros:
        from vision_cal.camera.export import write_opencv, write_ros
        from vision_cal.camera.fixed import camera_of

        cam = camera_of(doc, args.camera, file=args.calibration)
        written += [write_opencv(args.opencv, cam)] if args.opencv else []
        written += write_ros(args.ros, cam) if args.ros else []
    if args.urdf or args.yaml:
        written = export(doc, urdf=args.urdf, yaml_path=args.yaml) + written
    for path in written:
        if not args.quiet:
            print(f"wrote {path}")
    return 0
