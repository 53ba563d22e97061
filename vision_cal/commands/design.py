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
    p.add_argument("--verify", metavar="CAL.json",
                   help="plan a short check of this calibration instead (about ten marks "
                        "across the workspace, both elbows): draw it on a fresh sheet, then "
                        "`vision-cal verify CAL.json OUT/`")
    p.add_argument("--iso9283", type=int, default=0, metavar="N",
                   help="with --verify: also visit ISO 9283's five points N times each (small "
                        "known offsets keep the dots apart) for positioning accuracy AP and "
                        "repeatability RP")
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
    c = p.add_argument_group("camera on the arm (vision_cal/camera/arm_design.py)")
    c.add_argument("--camera-on-arm", action="store_true",
                   help="plan camera poses over a marker field (vision-cal sheet --field) "
                        "instead of pen marks: session.json poses and program.prg")
    c.add_argument("--n-poses", type=int, default=24, metavar="N",
                   help="camera poses (default 24)")
    c.add_argument("--mount", choices=("flange", "link2"), default="flange",
                   help="the camera turns with joint 4 (flange, default) or not (link2)")
    c.add_argument("--trigger", choices=("output", "wait"), default="output",
                   help="camera trigger per pose: an output pulse (default) or a pause")
    c.add_argument("--trigger-output", type=int, default=8, metavar="BIT",
                   help="output bit pulsed for the camera (default 8)")


def run(args) -> int:
    from vision_cal.design.stage import design_stage
    from vision_cal.errors import VisionCalError

    if args.camera_on_arm:
        return _camera_on_arm(args)

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
    if args.verify is not None and args.pilot is not None:
        raise VisionCalError("give either --pilot (the informative plan) or --verify (a check "
                             "of a calibration), not both", field="--verify")
    if args.pilot:
        from vision_cal.dataset.io import read_json
        from vision_cal.dataset.trust import require_ready_pilot

        require_ready_pilot(read_json(args.pilot), args.pilot)
    check = args.verify is not None
    if args.iso9283 and not check or not 0 <= args.iso9283 <= 30:
        raise VisionCalError(f"expected 1..30 cycles with --verify, got {args.iso9283}",
                             field="--iso9283")
    r = design_stage(args.robot, args.sheet, args.out, pilot=args.verify if check else args.pilot,
                     program=None if args.program == "none" else args.program,
                     n_calibration=10 if check else args.n_calibration,
                     n_validation=0 if check else args.n_validation,
                     safety_mm=args.safety_mm, seed=args.seed,
                     stage="verify" if check else None,
                     iso9283_cycles=args.iso9283 if check else 0)
    import sys

    for w in r.info.get("warnings", []):
        print(f"vision-cal: warning: {w}", file=sys.stderr)
    if not args.quiet:
        print(f"{r.stage} plan: {r.n_marks} marks, {r.duration_s:.1f} s of motion")
        if r.stage == "pilot":
            print(f"every mark stays {r.info['worst_case_clearance_mm']:.1f} mm clear of markers "
                  f"and edges for {r.info['placements_checked']} placements within the "
                  "robot file's placement_tolerance")
        elif r.stage == "verify":
            print(f"a check of {args.verify}: draw it on a fresh sheet, photograph it into "
                  f"{args.out}, then: vision-cal verify {args.verify} {args.out}")
        else:
            print(f"placed with the pilot's model, {r.info['safety_mm']:.1f} mm of safety")
        for p in (r.session_path, r.trajectory_path, r.program_path):
            if p is not None:
                print(f"wrote {p}")
    return 0


def _camera_on_arm(args) -> int:
    from vision_cal.camera.arm_design import design_camera_on_arm
    from vision_cal.dataset.io import output_dir, read_json
    from vision_cal.dataset.robot import load_robot_file
    from vision_cal.dataset.session import load_sheet_file

    out = output_dir(args.out, field="--out")
    robot = load_robot_file(args.robot)
    sheet = load_sheet_file(args.sheet)
    a, b = design_camera_on_arm(robot, sheet, read_json(args.sheet), out, n_poses=args.n_poses,
                                mount=args.mount, trigger=args.trigger,
                                output_bit=args.trigger_output, seed=args.seed)
    if not args.quiet:
        print(f"camera poses: {args.n_poses} ({args.mount} mount); put the photos beside "
              f"{a} (and your camera's lens in it if you know it: camera: size_px, K, dist), "
              f"then vision-cal handeye {out} --out CAL/")
        print(f"wrote {a}")
        print(f"wrote {b}")
    return 0
