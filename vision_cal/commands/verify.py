"""``vision-cal verify``: is the robot still calibrated? A short check against calibration.json."""

from __future__ import annotations

from vision_cal.commands import JOBS, request

NAME = "verify"
HELP = ("check a calibration on a short plan drawn later (design --verify): each mark's error, "
        "which parameters moved (with std) and a verdict: still good, re-zero a joint, or "
        "recalibrate")
EXAMPLES = """\
examples:
  vision-cal design robot.yaml --sheet sheet/sheet.json --verify cal/calibration.json --out check/
      about ten marks across the workspace, both elbows (draw them on a fresh sheet,
      photograph it into check/)
  vision-cal verify cal/calibration.json check/
      -> check_verify/verify.json and the verdict

The sheet's placement (base x, y and z1, which includes the robot's rotation to the sheet)
is refitted first: a new sheet lies elsewhere, so joint 1's zero cannot be checked on it.
Exit code 0 whatever the verdict (read it, or verify.json's "verdict").
"""


def add_arguments(p) -> None:
    p.add_argument("calibration", metavar="CAL.json", help="the calibration.json to check")
    p.add_argument("folder", metavar="PHOTOS/",
                   help="the check's folder: session.json from design --verify and the photos")
    p.add_argument("-o", "--out", metavar="DIR", default=None,
                   help="folder for verify.json and the measurement cache (default: "
                        "PHOTOS_verify beside the photos; the photos' folder is never written)")
    p.add_argument("--force", action="store_true",
                   help="check even marks outside what the calibration was calibrated for "
                        "(calibration.json valid_for: joint ranges, approach sides, joint 4), "
                        "the extrapolation stated in verify.json and on the console")
    p.add_argument("-j", "--jobs", type=JOBS, default=None, metavar="N",
                   help="processes that measure photos (default: every core)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.actions.verify import VerifyRequest, verify

    return verify(request(args, VerifyRequest)).show(quiet=args.quiet)
