"""``vision-cal locate``: where a pixel of a still camera is, in robot and sheet mm."""

from __future__ import annotations

from vision_cal.commands import CAMERA, HEIGHT_MM, JOINT_DEG, bounded, request

NAME = "locate"
HELP = ("map a pixel of a calibrated camera (calibration.json cameras: still, or on the arm at "
        "given joints) to the robot frame")
EXAMPLES = """\
examples:
  vision-cal locate out/calibration.json --pixel 812.5 433.0
  vision-cal locate out/calibration.json --pixel 812.5 433.0 --z-mm 50 --robot robot.yaml
  vision-cal locate out/calibration.json --csv pixels.csv -o points.csv
  vision-cal locate arm_cal/calibration.json --pixel 320 240 --joints 30 60 45
  vision-cal locate arm_cal/calibration.json --pixel 320 240 --photo pose_003.png

A camera on the arm (vision-cal handeye) needs the arm's command when the photo was taken:
--joints Q1 Q2 [Q4] (deg), or --photo NAME for one of its calibration photos; its std then
holds the robot's repeatability.

--csv reads id,u_px,v_px (and optionally z_mm) and writes id,u_px,v_px,z_mm,x_mm,y_mm,
x_std_mm,y_std_mm,sheet_x_mm,sheet_y_mm (+ q1_deg,q2_deg,status with --robot). The std is
the camera's (its pose, focal length and the robot's base), the pixel taken as exact.
"""


def add_arguments(p) -> None:
    p.add_argument("calibration", metavar="CALIBRATION.json",
                   help="a calibration.json with a camera (\"cameras\"): a still camera's "
                        "(`vision-cal PHOTOS/` on photos taken from one place) or the arm "
                        "camera's (`vision-cal handeye`)")
    p.add_argument("--pixel", type=bounded(-1, 100000, unit="px"), nargs=2, metavar=("U", "V"),
                   help="pixel (OpenCV convention: the top-left pixel's centre is 0 0)")
    p.add_argument("--csv", metavar="PIXELS.csv", help="a list: id,u_px,v_px[,z_mm]")
    p.add_argument("-o", "--out", metavar="POINTS.csv", help="with --csv: write here "
                   "(default: print)")
    p.add_argument("--camera", type=CAMERA, default=0, metavar="N",
                   help="which of calibration.json's cameras (default 0)")
    p.add_argument("--z-mm", type=HEIGHT_MM, default=0.0, metavar="H",
                   help="height of the point above the sheet's plane (default 0)")
    p.add_argument("--robot", metavar="ROBOT.yaml", help="robot file: also print the "
                   "compensated joint command (its joint limits)")
    p.add_argument("--joints", type=JOINT_DEG, nargs="+", metavar="Q",
                   help="a camera on the arm: the commanded joints Q1 Q2 [Q4] (deg) the photo "
                        "was taken at")
    p.add_argument("--photo", metavar="NAME", help="a camera on the arm: the command of this "
                   "calibration photo (calibration.json poses)")
    p.add_argument("--elbow", type=int, choices=(1, -1), default=1,
                   help="elbow solution of the joint command (default +1)")
    p.add_argument("--force", action="store_true",
                   help="locate even outside what the calibration was calibrated for "
                        "(calibration.json valid_for: the heights the camera can locate at, "
                        "the joints and approach sides it saw), the extrapolation stated on "
                        "the console and in the CSV (outside_valid_for)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.actions.console import show
    from vision_cal.actions.locate import LocateRequest, locate_pixels

    return show(locate_pixels(request(args, LocateRequest)), quiet=args.quiet)
