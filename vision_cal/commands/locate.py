"""``vision-cal locate``: where a pixel of a still camera is, in robot and sheet mm."""

from __future__ import annotations

from vision_cal.commands import CAMERA, HEIGHT_MM, JOINT_DEG, bounded, request

#: a flange pose: x y z (mm, within any arm's reach) and a quaternion (its norm checked)
FLANGE_POSE = bounded(-10000, 10000)

NAME = "locate"
HELP = ("map a pixel of a calibrated camera (calibration.json cameras: still, or on the arm at "
        "given joints or flange pose) to the robot frame")
EXAMPLES = """\
examples:
  vision-cal locate out/calibration.json --pixel 812.5 433.0
  vision-cal locate out/calibration.json --pixel 812.5 433.0 --z-mm 50 --robot robot.yaml
  vision-cal locate out/calibration.json --csv pixels.csv -o points.csv
  vision-cal locate arm_cal/calibration.json --pixel 320 240 --joints 30 60 45
  vision-cal locate arm_cal/calibration.json --pixel 320 240 --photo pose_003.png

A camera on a SCARA's arm (vision-cal handeye FOLDER/) needs the arm's command when the photo
was taken: --joints Q1 Q2 [Q4] (deg), or --photo NAME for one of its calibration photos; its
std then holds the robot's repeatability.

A camera on any arm's flange (vision-cal handeye PHOTOS/ --robot-poses POSES --mount arm)
needs the flange pose the controller reported for the photo: --flange-pose X Y Z QX QY QZ QW
(mm, T_robot_flange), or --photo NAME (one of the calibration's photos, or with --robot-poses
POSES one of those poses: a folder of per-photo pose files or a CSV, as handeye reads them;
a photo column in --csv picks each pixel's). The pixel meets the board's plane (--plane
board, --z-mm above it) or the robot frame's z = H (--plane robot); its std holds the
calibration's covariance, the lens and the robot's pose error (per photo and kinematic), and
a pose far from every calibration photo's (valid_for.flange_poses; give the arm's joints with
--joints, or joints_deg in the pose files, to have its configuration checked) is not located
without --force:
  vision-cal locate he/calibration.json --pixel 640 480 --flange-pose 412.5 -80.2 305.0 0 1 0 0
  vision-cal locate he/calibration.json --csv pixels.csv --robot-poses poses/ -o points.csv

--csv reads id,u_px,v_px (and optionally z_mm, and photo for a camera on any arm's flange)
and writes id,u_px,v_px,z_mm,x_mm,y_mm,x_std_mm,y_std_mm,sheet_x_mm,sheet_y_mm (+ q1_deg,
q2_deg,status with --robot; a camera on any arm's flange: the board's frame as the sheet's,
+ robot_z_mm,z_std_mm,plane,flange_pose). The std is the camera's (its pose, focal length
and the robot's base), the pixel taken as exact.
"""


def add_arguments(p) -> None:
    p.add_argument("calibration", metavar="CALIBRATION.json",
                   help="a calibration.json with a camera (\"cameras\"): a still camera's "
                        "(`vision-cal PHOTOS/` on photos taken from one place) or the arm "
                        "camera's (`vision-cal handeye`)")
    p.add_argument("--pixel", type=bounded(-1, 100000, unit="px"), nargs=2, metavar=("U", "V"),
                   help="pixel (OpenCV convention: the top-left pixel's centre is 0 0)")
    p.add_argument("--csv", metavar="PIXELS.csv", help="a list: id,u_px,v_px[,z_mm][,photo]")
    p.add_argument("-o", "--out", metavar="POINTS.csv", help="with --csv: write here "
                   "(default: print)")
    p.add_argument("--camera", type=CAMERA, default=0, metavar="N",
                   help="which of calibration.json's cameras (default 0)")
    p.add_argument("--z-mm", type=HEIGHT_MM, default=0.0, metavar="H",
                   help="height of the point above the sheet's plane (a camera on any arm's "
                        "flange: the calibration board's, or with --plane robot the robot "
                        "frame's z; default 0)")
    p.add_argument("--robot", metavar="ROBOT.yaml", help="robot file: also print the "
                   "compensated joint command (its joint limits)")
    p.add_argument("--joints", type=JOINT_DEG, nargs="+", metavar="Q",
                   help="a camera on a SCARA's arm: the commanded joints Q1 Q2 [Q4] (deg) the "
                        "photo was taken at; on any arm's flange, with --flange-pose: the "
                        "arm's joints there (deg), its configuration checked")
    p.add_argument("--photo", metavar="NAME", help="a camera on the arm: the command (SCARA) "
                   "or flange pose (any arm) of this calibration photo, or of this pose of "
                   "--robot-poses")
    p.add_argument("--flange-pose", type=FLANGE_POSE, nargs=7,
                   metavar=("X", "Y", "Z", "QX", "QY", "QZ", "QW"),
                   help="a camera on any arm's flange: the flange pose the controller "
                        "reported for the photo (T_robot_flange: mm and a quaternion)")
    p.add_argument("--robot-poses", metavar="POSES", help="a camera on any arm's flange: "
                   "flange poses by photo (a folder of per-photo pose files in metres or a "
                   "CSV photo,x_mm,y_mm,z_mm,qx,qy,qz,qw, as vision-cal handeye reads them), "
                   "picked by --photo or the CSV's photo column")
    p.add_argument("--plane", choices=("board", "robot"),
                   help="a camera on any arm's flange: the plane the pixel lies on, the "
                        "calibration board's (default; --z-mm above it) or the robot frame's "
                        "z = --z-mm")
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
    from vision_cal.actions.locate import LocateRequest, locate_pixels

    return locate_pixels(request(args, LocateRequest)).show(quiet=args.quiet)
