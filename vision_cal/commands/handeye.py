"""``vision-cal handeye``: a camera on the arm calibrates the robot and finds its mount."""

from __future__ import annotations

from vision_cal.commands import request

NAME = "handeye"
HELP = ("calibrate the robot and T_flange_camera from photos taken by the arm's camera "
        "(session.json poses; no pen), or a camera from pose pairs another tool measured "
        "(--poses)")
EXAMPLES = """\
examples:
  vision-cal handeye arm_photos/ --out arm_cal/     -> arm_cal/calibration.json
  vision-cal handeye --poses pairs.json --out he/   -> he/calibration.json (T_flange_camera)
  vision-cal handeye --poses pairs.csv --units m --mount fixed --z-mm 12.5 --out he/

--poses: pairs of T_robot_flange and T_camera_target (4x4, or x,y,z,yaw and OpenCV
rvec/tvec; JSON or CSV; docs/format.md, "Hand-eye from pose pairs"). A SCARA's poses cannot
see the camera's height: --z-mm gives the target origin's height (arm: in the robot frame;
fixed: in the flange frame), else it is reported not identifiable.

session.json lists "poses" ({"image", "joints_deg", "j4_deg"}), the declared camera lens,
"camera_mount" (flange | link2) and the marker field (vision-cal sheet --field); see
docs/format.md, "Cameras". At most 500 poses.

Writes OUT/calibration.json only (an earlier run's results go to OUT/previous/): no
report.html yet (no --report); calibration.json's "poses" (each photo's residual) and
"verdict" hold what a report would. The photos are measured in --jobs processes.
"""


def add_arguments(p) -> None:
    p.add_argument("folder", metavar="FOLDER", nargs="?", default=None,
                   help="dataset folder with session.json poses (photos of the arm's camera)")
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--poses", metavar="PAIRS", default=None,
                   help="pose pairs file (JSON vision-cal/poses/1, or CSV) instead of FOLDER")
    p.add_argument("--units", choices=("mm", "cm", "in", "m"), default=None,
                   help="--poses: the file's lengths (default: the file's units, else mm)")
    p.add_argument("--mount", choices=("arm", "fixed"), default=None,
                   help="--poses: the camera rides on the flange (arm, default) or stands "
                        "still watching a target on the flange (fixed)")
    p.add_argument("--z-mm", type=float, default=None, dest="z_mm", metavar="H",
                   help="--poses: the target origin's height (mm; arm: robot frame, fixed: "
                        "flange frame), which a SCARA's motion cannot see")
    p.add_argument("-j", "--jobs", type=int, default=None, metavar="N",
                   help="processes that measure the photos (default: every core; the same "
                        "result for any N)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.errors import VisionCalError

    if (args.folder is None) == (args.poses is None):
        raise VisionCalError("give FOLDER (photos of the arm's camera) or --poses PAIRS "
                             "(pose pairs), one of them", field="--poses")
    from vision_cal.actions.console import show

    if args.poses is not None:
        from vision_cal.actions.handeye import HandeyeRequest, handeye_pairs

        return show(handeye_pairs(request(args, HandeyeRequest)), quiet=args.quiet)
    for name in ("units", "mount", "z_mm"):
        if getattr(args, name) is not None:
            raise VisionCalError("applies to --poses only", field=f"--{name.replace('_', '-')}")
    from vision_cal.actions.arm_camera import ArmCameraRequest, calibrate_arm

    return show(calibrate_arm(request(args, ArmCameraRequest)), quiet=args.quiet)
