"""``vision-cal handeye``: a camera on the arm calibrates the robot and finds its mount."""

from __future__ import annotations

from vision_cal.commands import HEIGHT_MM, JOBS, request

NAME = "handeye"
HELP = ("calibrate the robot and T_flange_camera from photos taken by the arm's camera "
        "(session.json poses; no pen), or a camera from pose pairs another tool measured "
        "(--poses), or any arm's camera from photos of a board and the robot's poses "
        "(--robot-poses)")
EXAMPLES = """\
examples:
  vision-cal handeye photos/ --robot-poses poses/ --sheet board/sheet.json --mount fixed -o he/
      any arm: -> he/calibration.json (T_robot_camera, T_flange_board)
  vision-cal handeye arm_photos/ --out arm_cal/     -> arm_cal/calibration.json
  vision-cal handeye --poses pairs.json --out he/   -> he/calibration.json (T_flange_camera)
  vision-cal handeye --poses pairs.csv --units m --mount fixed --z-mm 12.5 --out he/

--poses: pairs of T_robot_flange and T_camera_target (4x4, or x,y,z,yaw and OpenCV
rvec/tvec; JSON or CSV; docs/format.md, "Hand-eye from pose pairs"). A SCARA's poses cannot
see the camera's height: --z-mm gives the target origin's height (arm: in the robot frame;
fixed: in the flange frame), else it is reported not identifiable.

--robot-poses (any arm, six axes or more): PHOTOS/ holds photos of a board (a ChArUco board
from `vision-cal sheet --charuco 5x7 --square-mm 36.195 --marker-mm 18.256 --dictionary
DICT_6X6_250`, or any sheet.json of markers: --sheet), and POSES the flange pose the
controller reported for each photo: a folder of per-photo files named after the photos
(7.yaml for 7.png: x y z in metres, qx qy qz qw, as ROS tools write them) or a CSV
photo,x_mm,y_mm,z_mm,qx,qy,qz,qw. --mount fixed: a still camera, the board on the flange
(-> T_robot_camera, T_flange_board); arm: the camera on the flange, the board still
(-> T_flange_camera, T_robot_board). The lens is estimated unless --camera gives it. The
verdict predicts each photo from the others (docs/format.md, "Photos and the robot's poses").

session.json lists "poses" ({"image", "joints_deg", "j4_deg"}), the declared camera lens,
"camera_mount" (flange | link2) and the marker field (vision-cal sheet --field); see
docs/format.md, "Cameras". At most 500 poses.

Writes OUT/calibration.json only (an earlier run's results go to OUT/previous/): no
report.html yet (no --report); calibration.json's "poses" (each photo's residual) and
"verdict" hold what a report would. The photos are measured in --jobs processes.
"""


def add_arguments(p) -> None:
    p.add_argument("folder", metavar="FOLDER", nargs="?", default=None,
                   help="dataset folder with session.json poses (photos of the arm's camera); "
                        "with --robot-poses: the photos of the board")
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--poses", metavar="PAIRS", default=None,
                   help="pose pairs file (JSON vision-cal/poses/1, or CSV) instead of FOLDER")
    p.add_argument("--robot-poses", metavar="POSES", default=None, dest="robot_poses",
                   help="the controller's flange pose for each photo of FOLDER (a folder of "
                        "7.yaml files in metres, or a CSV in mm): any arm's hand-eye")
    p.add_argument("--sheet", metavar="BOARD", default=None,
                   help="--robot-poses: the board's sheet.json (vision-cal sheet --charuco ...)")
    p.add_argument("--camera", metavar="LENS", default=None,
                   help="--robot-poses: the lens (a JSON with a camera block: size_px, K, dist; "
                        "default: estimated from the photos)")
    p.add_argument("--units", choices=("mm", "cm", "in", "m"), default=None,
                   help="--poses: the file's lengths (default: the file's units, else mm)")
    p.add_argument("--mount", choices=("arm", "fixed"), default=None,
                   help="--poses, --robot-poses: the camera rides on the flange (arm, --poses' "
                        "default) or stands still watching a target on the flange (fixed)")
    p.add_argument("--z-mm", type=HEIGHT_MM, default=None, dest="z_mm", metavar="H",
                   help="--poses: the target origin's height (mm; arm: robot frame, fixed: "
                        "flange frame), which a SCARA's motion cannot see")
    p.add_argument("-j", "--jobs", type=JOBS, default=None, metavar="N",
                   help="processes that measure the photos (default: every core; the same "
                        "result for any N)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.errors import VisionCalError

    if args.robot_poses is not None:     # any arm: photos of a board and the robot's poses
        return _photos_and_poses(args, VisionCalError)
    if (args.folder is None) == (args.poses is None):
        raise VisionCalError("give FOLDER (photos of the arm's camera) or --poses PAIRS "
                             "(pose pairs), one of them", field="--poses")
    for name in ("sheet", "camera"):
        if getattr(args, name) is not None:
            raise VisionCalError("applies to --robot-poses only", field=f"--{name}")
    if args.poses is not None:
        from vision_cal.actions.handeye import HandeyeRequest, handeye_pairs

        return handeye_pairs(request(args, HandeyeRequest)).show(quiet=args.quiet)
    for name in ("units", "mount", "z_mm"):
        if getattr(args, name) is not None:
            raise VisionCalError("applies to --poses only", field=f"--{name.replace('_', '-')}")
    from vision_cal.actions.arm_camera import ArmCameraRequest, calibrate_arm

    return calibrate_arm(request(args, ArmCameraRequest)).show(quiet=args.quiet)


def _photos_and_poses(args, error) -> int:
    """``handeye PHOTOS/ --robot-poses POSES --sheet BOARD --mount M``: the options checked."""
    if args.poses is not None:
        raise error("give --robot-poses (photos and the robot's poses) or --poses (pose "
                    "pairs), not both", field="--robot-poses")
    if args.folder is None:
        raise error("--robot-poses needs FOLDER, the photos", field="FOLDER")
    for name in ("sheet", "mount"):
        if getattr(args, name) is None:
            raise error("--robot-poses needs it: " + (
                "the board's sheet.json" if name == "sheet" else
                "fixed (a still camera, the board on the flange) or arm (the camera on the "
                "flange)"), field=f"--{name}")
    for name in ("units", "z_mm"):
        if getattr(args, name) is not None:
            raise error("applies to --poses only (--robot-poses: a folder in metres, a CSV "
                        "in mm)", field=f"--{name.replace('_', '-')}")
    from vision_cal.actions.handeye import HandeyePhotosRequest, handeye_photos

    return handeye_photos(request(args, HandeyePhotosRequest)).show(quiet=args.quiet)
