"""``vision-cal design``: what the robot must draw (the pilot, then the informative plan)."""

from __future__ import annotations

from vision_cal.commands import SEED, bounded, request

NAME = "design"
HELP = ("design the marks the robot draws on the printed sheet: the pilot (no --pilot) or, "
        "from the pilot's calibration, the informative plan; writes session.json (no images "
        "yet), trajectory.csv and a robot program")
EXAMPLES = """\
examples:
  vision-cal design fixtures/robot_sm5.yaml --sheet sheet/sheet.json --out pilot/
      the pilot: 9 marks that land on free paper however the robot really stands
      (within the robot file's placement_tolerance); draw it, photograph it, then
  vision-cal pilot/ --out pilot_cal/
  vision-cal design fixtures/robot_sm5.yaml --sheet sheet/sheet.json --out plan/ \\
      --pilot pilot_cal/calibration.json --program spel
      the informative plan (30 calibration + 8 validation marks, both elbows, both
      approach sides), placed with the pilot's model
"""


def add_arguments(p) -> None:
    p.add_argument("robot", metavar="ROBOT.yaml",
                   help="robot file (YAML or JSON): the session's robot block plus limits, "
                        "placement tolerance, pen heights (vision_cal/dataset/robot.py)")
    p.add_argument("--sheet", required=True, metavar="SHEET.json",
                   help="the sheet.json written by `vision-cal sheet`")
    p.add_argument("--survey", default=None, metavar="SURVEY.json",
                   help="the sheet as printed (vision-cal survey), copied into the plan's "
                        "folder for the calibration; default: a survey.json beside --sheet")
    p.add_argument("-o", "--out", required=True, metavar="PLAN/",
                   help="folder for session.json, trajectory.csv and the program (the photos "
                        "go here later)")
    p.add_argument("--pilot", metavar="CAL.json",
                   help="the pilot's calibration.json: design the informative plan with it")
    p.add_argument("--verify", metavar="CAL.json",
                   help="plan a short check of this calibration instead (about ten marks "
                        "across the workspace, both elbows): draw it on a fresh sheet, then "
                        "`vision-cal verify CAL.json OUT/`")
    p.add_argument("--iso9283", type=bounded(0, 30, integer=True), default=0, metavar="N",
                   help="with --verify: also visit ISO 9283's five points N times each (small "
                        "known offsets keep the dots apart) for positioning accuracy AP and "
                        "repeatability RP")
    p.add_argument("--program", choices=("spel", "csv", "rapid", "val3", "evplus", "pacscript",
                                          "tp", "none"), default="spel",
                   help="robot program: spel (Epson SPEL+ program.prg, default), csv (neutral "
                        "point list program_points.csv), rapid (ABB program.mod), val3 "
                        "(Staubli application program/program.pjx), evplus (Omron/Adept "
                        "program.v2), pacscript (Denso program.pcs), tp (Fanuc program.ls; "
                        "docs/controllers.md) or none")
    p.add_argument("--n-calibration", type=bounded(3, 1000, integer=True), default=30, metavar="N",
                   help="informative plan: calibration marks (default 30)")
    p.add_argument("--n-validation", type=bounded(0, 1000, integer=True), default=8, metavar="N",
                   help="informative plan: held-out validation marks (default 8)")
    p.add_argument("--safety-mm", type=bounded(0, 200, unit="mm"), default=None, metavar="MM",
                   help="informative plan: extra clearance from markers and edges (default: "
                        "5 mm + 6 x the pilot model's largest predicted std on the sheet)")
    p.add_argument("--seed", type=SEED, default=0, help="random seed of the design (default 0)")
    p.add_argument("--placements", type=bounded(1, 12, integer=True), default=None, metavar="N",
                   help="plan N placements of the sheet turned about joint 1 (a joint "
                        "calibration, `calibrate ... --joint`): OUT/placeK/ each with its "
                        "robot.yaml and pilot design, OUT/placements.json")
    c = p.add_argument_group("camera on the arm (vision_cal/camera/arm_design.py)")
    c.add_argument("--camera-on-arm", action="store_true",
                   help="plan camera poses over a marker field (vision-cal sheet --field) "
                        "instead of pen marks: session.json poses and program.prg")
    c.add_argument("--n-poses", type=bounded(8, 500, integer=True), default=24, metavar="N",
                   help="camera poses (default 24)")
    c.add_argument("--repeats", type=bounded(0, 500, integer=True), default=6, metavar="N",
                   help="poses photographed twice, leaving and coming back from the same "
                        "sides: the verdict measures the robot's repeatability from them "
                        "(default 6; 0: none, the robot block's repeatability_mm is taken)")
    c.add_argument("--mount", choices=("flange", "link2"), default="flange",
                   help="the camera turns with joint 4 (flange, default) or not (link2)")
    c.add_argument("--trigger", choices=("output", "wait"), default="output",
                   help="camera trigger per pose: an output pulse (default) or a pause")
    c.add_argument("--trigger-output", type=bounded(0, 9999, integer=True), default=8,
                   metavar="BIT",
                   help="output bit pulsed for the camera (default 8)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.actions.design import DesignRequest, design

    return design(request(args, DesignRequest)).show(quiet=args.quiet)
