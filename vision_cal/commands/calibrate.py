"""``vision-cal calibrate``: measure and calibrate dataset folders."""

from __future__ import annotations

from vision_cal.config import METHODS

NAME = "calibrate"
HELP = "measure the photographs of a dataset folder and calibrate the robot"
EXAMPLES = """\
examples:
  vision-cal fixtures/paper_sm5 --out /tmp/x               least squares (default)
  vision-cal fixtures/paper_sm5 --method paper --out /tmp/x  the seed paper's circles
  vision-cal images/ --out out/ --jobs 2                   photographs, in parallel
  vision-cal calibrate A/ B/ C/ --joint --out X/           one robot, three placements
"""


def add_arguments(p) -> None:
    p.add_argument("folders", nargs="+", metavar="DIR", help="dataset folder(s) with session.json")
    p.add_argument("-o", "--out", default=None,
                   help="output folder (default: out/<folder name>); with several folders, "
                        "one sub-folder each")
    p.add_argument("--method", choices=METHODS, default=METHODS[0],
                   help="lsq: least squares with effect diagnosis (default); paper: the seed "
                        "paper's three-point circles")
    p.add_argument("-j", "--jobs", type=int, default=None, help="parallel photo measurement "
                   "(default: the number of cores)")
    p.add_argument("--truth", action="store_true",
                   help="compare with truth.json (synthetic data only)")
    p.add_argument("--report", action="store_true", help="also write report.json and report.html")
    p.add_argument("--survey", default=None, metavar="SURVEY.json",
                   help="the sheet as printed (vision-cal survey); default: a survey.json in "
                        "the dataset folder, if any")
    p.add_argument("--joint", action="store_true",
                   help="the folders are placements of one sheet (or several sheets) drawn by "
                        "one robot: fit one robot and one sheet pose each (robot frame R; "
                        "OUT/calibration.json, OUT/<folder>/calibration.json)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.actions.calibrate import CalibrateRequest, calibrate

    return calibrate(CalibrateRequest(tuple(args.folders), out=args.out, method=args.method,
                                      jobs=args.jobs, truth=args.truth, report=args.report,
                                      joint=args.joint, quiet=args.quiet,
                                      survey=args.survey))
