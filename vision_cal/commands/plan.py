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
    from vision_cal.dataset.csvio import (failed_report_path, read_targets, write_failed_targets,
                                          write_plan)
    from vision_cal.dataset.io import output_file
    from vision_cal.plan.compensate import plan_targets

    output_file(args.out, field="-o")
    if args.trajectory:
        output_file(args.trajectory, field="--trajectory")
    model, doc = load_calibration(args.calibration, which=args.model)
    ids, xy = read_targets(args.targets)
    planned = plan_targets(model, ids, xy, elbow=args.elbow, approach=tuple(args.approach))
    ok = [p for p in planned if p.status == "ok"]
    failed = [p for p in planned if p.status != "ok"]
    # the command file holds only what can be sent to the robot: no NaN, no failed row
    write_plan(args.out, [p.to_row() for p in ok])
    report = failed_report_path(args.out)
    if failed:
        write_failed_targets(report, [(p.id, *p.target_mm, p.reason) for p in failed])
        if ok:  # when none is planned, the error below says it once
            print(f"vision-cal: warning: {args.targets}: {summarise_failures(failed)}; "
                  f"all in {report}", file=sys.stderr)
    else:
        report.unlink(missing_ok=True)  # a stale report of an earlier run
    if args.trajectory and ok:
        from vision_cal.plan.compensate import write_plan_trajectory

        write_plan_trajectory(args.trajectory, ok, home_deg=doc.get("home_deg", (0.0, 0.0)))
    if not args.quiet:
        print(f"planned {len(planned) - len(failed)} of {len(planned)} targets "
              f"with the {args.model} model -> {args.out}")
    if not ok:
        print(f"vision-cal: error: {args.targets}: nothing could be planned with the "
              f"{args.model} model of {args.calibration}: {summarise_failures(failed)}; "
              f"all in {report}", file=sys.stderr)
        return 1
    return 0


def summarise_failures(failed, *, first: int = 3) -> str:
    """One line for any number of failed targets: counts per kind of reason, the first few."""
    kinds: dict[str, int] = {}
    for p in failed:
        k = next((k for k in ("out of reach", "singularity", "outside its limits",
                              "could not be inverted") if k in p.reason), "other")
        kinds[k] = kinds.get(k, 0) + 1
    counts = ", ".join(f"{n} {k}" for k, n in sorted(kinds.items(), key=lambda kv: -kv[1]))
    head = "; ".join(f"target {p.id}: {p.reason}" for p in failed[:first])
    more = f" (and {len(failed) - first} more)" if len(failed) > first else ""
    return f"{len(failed)} target(s) not planned ({counts}): {head}{more}"
