"""``vision-cal export``: a calibration as URDF (plus an effects side file) or YAML."""

from __future__ import annotations

from vision_cal.commands import CAMERA, request

NAME = "export"
HELP = ("export calibration.json as URDF joint origins (+ effects side file) or YAML; a still "
        "camera as OpenCV (--opencv) or ROS camera_info (--ros) YAML")
EXAMPLES = """\
examples:
  vision-cal fixtures/paper_sm5 --out /tmp/x
  vision-cal export /tmp/x/calibration.json --urdf /tmp/x/robot.urdf
  vision-cal export /tmp/x/calibration.json --yaml /tmp/x/calibration.yaml

--opencv and --ros need a calibration with a still camera (calibration.json "cameras":
photos of the robot's sheet taken from one place, README "Calibrate your camera"), or a
camera on any arm's flange (vision-cal handeye PHOTOS/ --robot-poses POSES --mount arm:
T_flange_camera, and the ROS transform from the flange, tool0, as a static transform); the
paper's calibration has none. For example, with the photos of a still camera in plan/:
  vision-cal plan/ --out cal/
  vision-cal export cal/calibration.json --opencv camera.yaml --ros camera_info.yaml
"""


def add_arguments(p) -> None:
    p.add_argument("calibration", metavar="CALIBRATION.json", help="the calibration.json to export")
    p.add_argument("--urdf", metavar="ROBOT.urdf", help="URDF with the calibrated joint origins; "
                   "effects go to ROBOT.effects.yaml beside it")
    p.add_argument("--yaml", metavar="FILE.yaml", help="parameters, std and effects as YAML")
    p.add_argument("--robot", metavar="ROBOT.yaml",
                   help="robot file: the URDF's joint limits, joint 3's travel and joint 4's "
                        "range (default: calibration.json's joint_limits_deg, which the "
                        "session's robot file gave; joints 3 and 4: vision_cal.model.motion's)")
    p.add_argument("--force", action="store_true",
                   help="export even a calibration whose verdict is 'not reliable', or a "
                        "robot model with an effect it could not identify (calibration.json "
                        "valid_for: a backlash seen from one side, a tool never turned), the "
                        "extrapolation stated in the files written and on the console")
    p.add_argument("--opencv", metavar="FILE.yaml", help="a still camera as OpenCV FileStorage "
                   "YAML: camera_matrix, distortion_coefficients, T_robot_camera (mm; a camera "
                   "on any arm's flange: T_flange_camera and T_robot_board)")
    p.add_argument("--ros", metavar="FILE.yaml", help="a still camera as ROS camera_info YAML, "
                   "and FILE.transform.yaml: robot -> camera optical frame (a camera on any "
                   "arm's flange: tool0 -> camera optical frame)")
    p.add_argument("--camera", type=CAMERA, default=0, metavar="N",
                   help="which of calibration.json's cameras (default 0)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.actions.export import ExportRequest, export_calibration

    return export_calibration(request(args, ExportRequest)).show(quiet=args.quiet)
