"""``vision-cal calibrate``: measure and calibrate dataset folders."""

from __future__ import annotations

from vision_cal.commands import JOBS, bounded, request
from vision_cal.config import METHODS

NAME = "calibrate"
HELP = "measure the photographs of a dataset folder and calibrate the robot"
EXAMPLES = """\
examples:
  vision-cal fixtures/paper_sm5 --out /tmp/x               least squares (default)
  vision-cal fixtures/paper_sm5 --method paper --out /tmp/x  the seed paper's circles
  vision-cal images/ --out out/ --jobs 2                   photographs, in parallel
  vision-cal calibrate A/ B/ C/ --joint --out X/           one robot, three placements
  vision-cal calibrate marks.csv --robot robot.yaml --sigma-mm 0.02 --out X/
                                       marks a laser tracker or CMM measured (no photos)

writes into OUT (default out/<folder name>):
  calibration.json   the model, std, covariance, effects, verdict (docs/format.md)
  measurement.json   every photo's marks as measured
  report.json, report.html   with --report
  summary.json       with several folders: one row each (OUT/<folder>/ each)
  previous/          an earlier run's results, moved aside before this run writes
  .cache/            the photos' detections, keyed by their bytes (safe to delete)
--joint: OUT/calibration.json (robot frame) and OUT/<folder>/calibration.json per
placement (their sheet frames, for plan). OUT is locked while written (.vision-cal.lock).
"""


def add_arguments(p) -> None:
    p.add_argument("folders", nargs="+", metavar="DIR",
                   help="dataset folder(s) with session.json, or a marks CSV "
                        "(id,q1_deg,q2_deg[,q4_deg],x_mm,y_mm[,approach1,approach2]) measured "
                        "by another instrument (docs/format.md, \"Marks from other instruments\")")
    p.add_argument("-o", "--out", default=None,
                   help="output folder (default: out/<folder name>); with several folders, "
                        "one sub-folder each")
    p.add_argument("--method", choices=METHODS, default=METHODS[0],
                   help="lsq: least squares with effect diagnosis (default); paper: the seed "
                        "paper's three-point circles")
    p.add_argument("-j", "--jobs", type=JOBS, default=None, help="parallel photo measurement "
                   "(default: the number of cores)")
    p.add_argument("--truth", action="store_true",
                   help="compare with truth.json (synthetic data only)")
    p.add_argument("--report", action="store_true", help="also write report.json and report.html")
    p.add_argument("--survey", default=None, metavar="SURVEY.json",
                   help="the sheet as printed (vision-cal survey); default: a survey.json in "
                        "the dataset folder, if any")
    p.add_argument("--bars-mm", type=bounded(50, 150, unit="mm"), nargs=2, default=None, dest="bars_mm",
                   metavar=("X", "Y"),
                   help="the sheet's two printed 100 mm bars as measured with a caliper (x, "
                        "then y): the paper's scale, which the marks cannot tell from the link "
                        "lengths (calibration.json printer_scale, paper_scale); default: the "
                        "sheet's measured_bar_mm, else a prior of 0.2 %%")
    p.add_argument("--joint", action="store_true",
                   help="the folders are placements of one sheet (or several sheets) drawn by "
                        "one robot: fit one robot and one sheet pose each (robot frame R; "
                        "OUT/calibration.json, OUT/<folder>/calibration.json)")


    p.add_argument("--robot", default=None, metavar="ROBOT.yaml",
                   help="a marks CSV: the robot file (the nominal model to start from)")
    p.add_argument("--sigma-mm", type=bounded(0, 100, lo_open=True, unit="mm"), default=None,
                   dest="sigma_mm", metavar="S",
                   help="a marks CSV: the instrument's stated accuracy (one std per axis, mm): "
                        "the noise floor of the verdict")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.actions.calibrate import CalibrateRequest, calibrate
    req = request(args, CalibrateRequest)
    # each folder's result is printed as soon as it is done (several take minutes each)
    return calibrate(req, tell=lambda o: o.show(quiet=args.quiet)).show(quiet=args.quiet)
