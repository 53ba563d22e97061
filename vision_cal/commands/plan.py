"""``vision-cal plan``: joint commands that hit sheet targets with a calibrated model."""

from __future__ import annotations

from vision_cal.commands import JOINT_DEG

NAME = "plan"
HELP = "plan joint commands for sheet targets with the calibrated (or nominal) model"
EXAMPLES = """\
examples:
  vision-cal fixtures/paper_sm5 --out /tmp/x
  vision-cal plan /tmp/x/calibration.json fixtures/targets_origin.csv -o /tmp/x/plan.csv
  vision-cal plan /tmp/x/calibration.json fixtures/targets_origin.csv -o /tmp/x/before.csv \\
      --model nominal

Targets outside what the calibration was calibrated for (calibration.json valid_for: joints
beyond the marks' range where its expected error grows beyond its own at the marks, an
approach side or a joint-4 angle never seen) are not planned: each goes to PLAN.failed.csv
with the reason and the command that would cover it, as a target out of reach does.

exit codes: 0 every target planned; 3 planned in part (the others in PLAN.failed.csv);
1 none planned; 2 a bad argument or input
"""


def add_arguments(p) -> None:
    p.add_argument("calibration", metavar="CALIBRATION.json", help="the calibration.json to plan with")
    p.add_argument("targets", metavar="TARGETS.csv", help="id,x_mm,y_mm")
    p.add_argument("-o", "--out", required=True, metavar="PLAN.csv",
                   help="id,q1_deg,q2_deg,approach1,approach2, status, reason, std_mm (how "
                        "well each target is expected to be hit: one std per axis of where it "
                        "lands) and its parts std_calibration_mm, std_repeatability_mm, "
                        "std_unexplained_mm, std_print_mm, std_paper_scale_mm; the targets "
                        "that cannot be planned also go to PLAN.failed.csv beside it")
    p.add_argument("--model", choices=("calibrated", "nominal"), default="calibrated",
                   help="plan with the calibrated model (default) or the nominal one (the "
                        "'before' column)")
    p.add_argument("--elbow", type=int, choices=(1, -1), default=1,
                   help="elbow solution: +1 sin(phi2) > 0 (default), -1 the other")
    p.add_argument("--approach", type=int, nargs=2, choices=(1, -1), default=(1, 1),
                   metavar=("S1", "S2"), help="approach sign of each joint (default: 1 1)")
    p.add_argument("--trajectory", metavar="TRAJ.csv",
                   help="also write the joint-space reference trajectory (0.016 s samples)")
    p.add_argument("--program", choices=("spel", "csv", "rapid", "val3", "evplus", "pacscript",
                                          "tp"), default=None,
                   help="also write a robot program beside PLAN.csv: spel (PLAN.prg, Epson "
                        "SPEL+), csv (PLAN_points.csv), rapid (PLAN.mod, ABB), val3 "
                        "(PLAN/PLAN.pjx, Staubli), evplus (PLAN.v2, Omron/Adept), pacscript "
                        "(PLAN.pcs, Denso) or tp (PLAN.ls, Fanuc); joint targets only "
                        "(docs/controllers.md); needs --robot")
    p.add_argument("--home", type=JOINT_DEG, nargs=2, metavar=("Q1", "Q2"), default=None,
                   help="joints (deg) the arm starts from (default: the robot file's "
                        "home_deg, else calibration.json's, which the session gave)")
    p.add_argument("--robot", metavar="ROBOT.yaml",
                   help="robot file: joint limits, speeds, pen heights for --program")
    p.add_argument("--force", action="store_true",
                   help="plan even with a calibration whose verdict is 'not reliable', or "
                        "targets outside what it was calibrated for (calibration.json "
                        "valid_for: joint ranges, approach sides, joint 4 with a tool never "
                        "turned), the extrapolation stated in PLAN.csv (outside_valid_for), "
                        "the program and on the console")
    p.add_argument("--approach4", type=int, choices=(1, -1), default=1,
                   help="approach sign of joint 4 when the plan turns it (default: 1)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.actions.plan import PlanRequest, plan

    return plan(PlanRequest(
        args.calibration, args.targets, args.out, model=args.model, elbow=args.elbow,
        approach=tuple(args.approach), trajectory=args.trajectory, program=args.program,
        home=None if args.home is None else tuple(args.home), robot=args.robot,
        force=args.force, approach4=args.approach4, quiet=args.quiet)).show(quiet=args.quiet)
