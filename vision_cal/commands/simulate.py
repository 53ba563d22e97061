"""``vision-cal simulate``: rehearse the robot's part (draw, photograph) on a simulated robot."""

from __future__ import annotations

from vision_cal.commands import SEED, bounded, request

NAME = "simulate"
HELP = ("rehearse without a robot: a simulated robot (your robot file plus hidden offsets and "
        "effects) draws a designed plan on the printed sheet and photographs it")
EXAMPLES = """\
examples:
  vision-cal robot-template --simulated -o true_robot.yaml
      a simulated robot: robot.yaml plus what the real one hides (edit its `hidden` block)
  vision-cal simulate pilot/ --truth true_robot.yaml --out pilot/
      draw pilot/program.prg, photograph the sheet into pilot/ (IMG_0001.png ..., truth.json)
  vision-cal simulate plan/ --truth true_robot.yaml --after pilot/ --out plan/
      the informative plan on the same sheet: the pilot's marks are on it too
  vision-cal simulate targets_plan.prg --truth true_robot.yaml --sheet sheet/sheet.json \\
      --targets targets.csv --out hits/
      the compensated targets on a fresh sheet; `vision-cal hits/ --out hits_cal/` then
      measures where each landed (calibration.json "targets")
  vision-cal simulate sheet/sheet.json --truth true_robot.yaml --out survey_photos/
      the blank sheet before any mark, 8 photos from several places tilted 10-30 deg,
      printed off its layout as true_robot.yaml's `print` says; then
      `vision-cal survey survey_photos/ --sheet sheet/sheet.json --out sheet/`

The photos are what `vision-cal PLAN/` then calibrates; truth.json (where each mark really
is, the true robot) is read only with --truth.
"""


def add_arguments(p) -> None:
    p.add_argument("plan", metavar="PLAN_DIR",
                   help="a folder written by `vision-cal design` (session.json and the program),"
                        " or a targets program of `vision-cal plan --program` (PLAN.prg with "
                        "PLAN.csv beside it; then give --sheet, and --targets), or a "
                        "sheet.json (or a session.json): the blank sheet, photographed for "
                        "a survey")
    p.add_argument("--sheet", metavar="SHEET.json",
                   help="targets program: the sheet it is drawn on (sheet.json)")
    p.add_argument("--targets", metavar="TARGETS.csv",
                   help="targets program: the targets, written as the marks' target_mm so "
                        "that calibrating the photos measures each target's error")
    p.add_argument("--truth", required=True, metavar="TRUE_ROBOT.yaml",
                   help="the simulated robot (vision-cal robot-template --simulated)")
    p.add_argument("-o", "--out", required=True, metavar="PHOTOS/",
                   help="folder for the photos and truth.json (PLAN_DIR itself, or another: "
                        "then session.json is copied there)")
    p.add_argument("--after", action="append", default=[], metavar="DIR",
                   help="a folder simulated before on the same sheet: its marks are on the "
                        "paper too (repeatable)")
    p.add_argument("--seed", type=SEED, default=None, metavar="N",
                   help="override the simulated robot file's seed")
    p.add_argument("--photos", type=bounded(1, 500, integer=True), default=None, metavar="N",
                   help="how many photos (default: the simulated robot's camera.photos; "
                        "a blank sheet 8)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.actions.simulate import SimulateRequest, simulate

    return simulate(request(args, SimulateRequest)).show(quiet=args.quiet)
