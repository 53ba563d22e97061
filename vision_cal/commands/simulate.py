"""``vision-cal simulate``: rehearse the robot's part (draw, photograph) on a simulated robot."""

from __future__ import annotations

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
  vision-cal simulate targets_plan.prg --truth true_robot.yaml --sheet sheet/sheet.json \
      --targets targets.csv --out hits/
      the compensated targets on a fresh sheet; `vision-cal hits/ --out hits_cal/` then
      measures where each landed (calibration.json "targets")

The photos are what `vision-cal PLAN/` then calibrates; truth.json (where each mark really
is, the true robot) is read only with --truth.
"""


def add_arguments(p) -> None:
    p.add_argument("plan", metavar="PLAN_DIR",
                   help="a folder written by `vision-cal design` (session.json and the program),"
                        " or a targets program of `vision-cal plan --program` (PLAN.prg with "
                        "PLAN.csv beside it; then give --sheet, and --targets)")
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
    p.add_argument("--seed", type=int, default=None, metavar="N",
                   help="override the simulated robot file's seed")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the library pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.dataset.io import written_together
    from vision_cal.dataset.out_folder import writing_into
    from vision_cal.errors import VisionCalError
    from vision_cal.render.rehearse import simulate_session

    if args.seed is not None and args.seed < 0:
        raise VisionCalError(f"expected a non-negative integer, got {args.seed}", field="--seed")
    # locked while written; the photos, session.json and truth.json are renamed into place
    # together at the end, so an interrupted run leaves none of them (issue 30)
    with writing_into(args.out, command="simulate", retire=False), written_together():
        r = simulate_session(args.plan, args.truth, args.out, after=args.after,
                             progress=not args.quiet, rng=args.seed, sheet_json=args.sheet,
                             targets=args.targets)
    if not args.quiet:
        extra = []
        if r.off_paper:
            extra.append(f"{len(r.off_paper)} off the paper")
        if r.on_marker:
            extra.append(f"{len(r.on_marker)} on a printed marker")
        print(f"the simulated robot drew {r.n_marks} marks"
              + (f" ({', '.join(extra)})" if extra else "")
              + f"; {len(r.photos)} photos -> {r.out_dir}/ (truth.json: where they really are)")
    return 0
