"""``vision-cal design``: what the robot must draw (the pilot, then the informative plan)."""

from __future__ import annotations

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
    p.add_argument("-o", "--out", required=True, metavar="PLAN/",
                   help="folder for session.json, trajectory.csv and the program (the photos "
                        "go here later)")
    p.add_argument("--pilot", metavar="CAL.json",
                   help="the pilot's calibration.json: design the informative plan with it")
    p.add_argument("--program", choices=("spel", "csv", "none"), default="spel",
                   help="robot program: spel (Epson SPEL+ program.prg, default), csv (neutral "
                        "point list program_points.csv) or none")
    p.add_argument("--n-calibration", type=int, default=30, metavar="N",
                   help="informative plan: calibration marks (default 30)")
    p.add_argument("--n-validation", type=int, default=8, metavar="N",
                   help="informative plan: held-out validation marks (default 8)")
    p.add_argument("--safety-mm", type=float, default=None, metavar="MM",
                   help="informative plan: extra clearance from markers and edges (default: "
                        "5 mm + 6 x the pilot model's largest predicted std on the sheet)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the design (default 0)")
    p.add_argument("--placements", type=int, default=None, metavar="N",
                   help="plan N placements of the sheet turned about joint 1 (a joint "
                        "calibration, `calibrate ... --joint`): OUT/placeK/ each with its "
                        "robot.yaml and pilot design, OUT/placements.json")


def run(args) -> int:
    from vision_cal.design.stage import design_stage
    from vision_cal.errors import VisionCalError

    if args.n_calibration < 3 or args.n_validation < 0:
        raise VisionCalError(f"expected at least 3 calibration and 0 validation marks, got "
                             f"{args.n_calibration} and {args.n_validation}",
                             field="--n-calibration")
    if args.safety_mm is not None and not args.safety_mm >= 0:
        raise VisionCalError(f"expected a non-negative number, got {args.safety_mm}",
                             field="--safety-mm")
    if args.placements is not None:   # several placements (design/placements.py, #21)
        from vision_cal.design.placements import design_placements

        if args.pilot:
            raise VisionCalError("--placements designs each placement's pilot; design the "
                                 "informative plans per placement folder", field="--pilot")
        places = design_placements(args.robot, args.sheet, args.out, args.placements,
                                   program=None if args.program == "none" else args.program,
                                   seed=args.seed)
        if not args.quiet:
            for p in places:
                print(f"{p['folder']}: {p['instruction']}")
        return 0
    r = design_stage(args.robot, args.sheet, args.out, pilot=args.pilot,
                     program=None if args.program == "none" else args.program,
                     n_calibration=args.n_calibration, n_validation=args.n_validation,
                     safety_mm=args.safety_mm, seed=args.seed)
    if not args.quiet:
        print(f"{r.stage} plan: {r.n_marks} marks, {r.duration_s:.1f} s of motion")
        if r.stage == "pilot":
            print(f"every mark stays {r.info['worst_case_clearance_mm']:.1f} mm clear of markers "
                  f"and edges for {r.info['placements_checked']} placements within the "
                  "robot file's placement_tolerance")
        else:
            print(f"placed with the pilot's model, {r.info['safety_mm']:.1f} mm of safety")
        for p in (r.session_path, r.trajectory_path, r.program_path):
            if p is not None:
                print(f"wrote {p}")
    return 0
