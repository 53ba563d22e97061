"""``vision-cal plan``: joint commands that hit sheet targets with a calibrated model."""

from __future__ import annotations

NAME = "plan"
HELP = "plan joint commands for sheet targets with the calibrated (or nominal) model"
EXAMPLES = """\
examples:
  vision-cal fixtures/paper_sm5 --out /tmp/x
  vision-cal plan /tmp/x/calibration.json fixtures/targets_origin.csv -o /tmp/x/plan.csv
  vision-cal plan /tmp/x/calibration.json fixtures/targets_origin.csv -o /tmp/x/before.csv \\
      --model nominal
"""


def add_arguments(p) -> None:
    p.add_argument("calibration", metavar="CALIBRATION.json")
    p.add_argument("targets", metavar="TARGETS.csv", help="id,x_mm,y_mm")
    p.add_argument("-o", "--out", required=True, metavar="PLAN.csv",
                   help="id,q1_deg,q2_deg,approach1,approach2 (+ status, reason)")
    p.add_argument("--model", choices=("calibrated", "nominal"), default="calibrated",
                   help="plan with the calibrated model (default) or the nominal one (the "
                        "'before' column)")
    p.add_argument("--elbow", type=int, choices=(1, -1), default=1,
                   help="elbow solution: +1 sin(phi2) > 0 (default), -1 the other")
    p.add_argument("--approach", type=int, nargs=2, choices=(1, -1), default=(1, 1),
                   metavar=("S1", "S2"), help="approach sign of each joint (default: 1 1)")
    p.add_argument("--trajectory", metavar="TRAJ.csv",
                   help="also write the joint-space reference trajectory (0.016 s samples)")


def run(args) -> int:
    import sys

    from vision_cal.dataset.calibration import load_calibration
    from vision_cal.dataset.csvio import read_targets, write_plan
    from vision_cal.dataset.io import output_file
    from vision_cal.plan.compensate import plan_targets

    output_file(args.out, field="-o")
    if args.trajectory:
        output_file(args.trajectory, field="--trajectory")
    model, doc = load_calibration(args.calibration, which=args.model)
    ids, xy = read_targets(args.targets)
    planned = plan_targets(model, ids, xy, elbow=args.elbow, approach=tuple(args.approach))
    write_plan(args.out, [p.to_row() for p in planned])
    failed = [p for p in planned if p.status != "ok"]
    for p in failed:
        print(f"vision-cal: warning: {args.targets}: target {p.id}: {p.reason}", file=sys.stderr)
    if args.trajectory:
        from vision_cal.plan.compensate import write_plan_trajectory

        ok = [p for p in planned if p.status == "ok"]
        write_plan_trajectory(args.trajectory, ok, home_deg=doc.get("home_deg", (0.0, 0.0)))
    if not args.quiet:
        print(f"planned {len(planned) - len(failed)} of {len(planned)} targets "
              f"with the {args.model} model -> {args.out}")
    return 0
