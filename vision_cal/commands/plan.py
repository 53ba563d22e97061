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
    p.add_argument("--program", choices=("spel", "csv"), default=None,
                   help="also write a robot program beside PLAN.csv: spel (PLAN.prg, Epson "
                        "SPEL+) or csv (PLAN_points.csv); needs --robot")
    p.add_argument("--home", type=float, nargs=2, metavar=("Q1", "Q2"), default=None,
                   help="joints (deg) the arm starts from (default: the robot file's "
                        "home_deg, else calibration.json's, which the session gave)")
    p.add_argument("--robot", metavar="ROBOT.yaml",
                   help="robot file: joint limits, speeds, pen heights for --program")
    p.add_argument("--approach4", type=int, choices=(1, -1), default=1,
                   help="approach sign of joint 4 when the plan turns it (default: 1)")


def run(args) -> int:
    import math
    import sys
    from pathlib import Path

    from vision_cal.dataset.calibration import load_calibration
    from vision_cal.dataset.csvio import (failed_report_path, read_target_theta, read_targets,
                                          write_failed_targets, write_plan)
    from vision_cal.dataset.io import output_file
    from vision_cal.plan.compensate import plan_targets
    from vision_cal.plan.uncertainty import load_covariance, predicted_std_mm

    output_file(args.out, field="-o")
    if args.trajectory:
        output_file(args.trajectory, field="--trajectory")
    robot = None
    if args.program and not args.robot:
        from vision_cal.errors import VisionCalError

        raise VisionCalError("--program needs --robot ROBOT.yaml (pen heights, speeds)",
                             field="--robot")
    if args.robot:
        from vision_cal.dataset.robot import load_robot_file

        robot = load_robot_file(args.robot)
        if args.program:
            robot.require_pen_heights()
    model, doc = load_calibration(args.calibration, which=args.model)
    ids, xy = read_targets(args.targets)
    limits = {} if robot is None else {"joint_limits_deg": robot.joint_limits_deg}
    theta = read_target_theta(args.targets)
    poses = None
    if theta is not None or model.tool is not None:   # joint 4 and the tool (plan/orient.py)
        from vision_cal.plan.orient import plan_poses

        if robot is not None:
            limits["joint4_limits_deg"] = robot.joint4_limits_deg
        poses = plan_poses(model, ids, xy, theta, elbow=args.elbow,
                           approach=(*args.approach, args.approach4),
                           q4_deg=robot.j4_deg if robot is not None else 0.0, **limits)
        planned = [p.target for p in poses]
        pose_of = {p.target.id: p for p in poses}
    else:
        planned = plan_targets(model, ids, xy, elbow=args.elbow, approach=tuple(args.approach),
                               **limits)
    cov = load_covariance(doc, model, file=args.calibration) if args.model == "calibrated" \
        else None
    ok = [p for p in planned if p.status == "ok"]
    failed = [p for p in planned if p.status != "ok"]
    if poses is None:
        q_ok, a_ok = [p.q_deg for p in ok], [p.approach for p in ok]
    else:
        q_ok = [(*p.q_deg, pose_of[p.id].q4_deg) for p in ok]
        a_ok = [(*p.approach, pose_of[p.id].approach4) for p in ok]
    std = (predicted_std_mm(model, cov, q_ok, a_ok)
           if cov is not None and ok else [float("nan")] * len(ok))
    # the command file holds only what can be sent to the robot: no NaN, no failed row
    # (an unknown std, as with the nominal model, is left empty)
    write_plan(args.out, [dict(p.to_row() if poses is None else pose_of[p.id].to_row(),
                               std_mm=float(s) if math.isfinite(s) else "")
                          for p, s in zip(ok, std)])
    report = failed_report_path(args.out)
    if failed:
        write_failed_targets(report, [(p.id, *p.target_mm, p.reason) for p in failed])
        if ok:  # when none is planned, the error below says it once
            print(f"vision-cal: warning: {args.targets}: {summarise_failures(failed)}; "
                  f"all in {report}", file=sys.stderr)
    else:
        report.unlink(missing_ok=True)  # a stale report of an earlier run
    home_deg = _home_deg(args, doc, robot)
    if args.trajectory and ok:
        from vision_cal.plan.compensate import write_plan_trajectory

        write_plan_trajectory(args.trajectory, ok, home_deg=home_deg)
    if args.program:
        from vision_cal.plan.compensate import to_planned_marks
        from vision_cal.program import program_path, program_points, write_program

        marks = to_planned_marks(ok, overshoot_deg=robot.overshoot_deg, role="target")
        joint4, tool = None, None
        if poses is not None:   # joint 4 turns: its via point on the approach side
            from vision_cal.plan.orient import controller_tool_mm

            joint4 = {p.target.id: (p.q4_deg, p.q4_deg - p.approach4 * robot.overshoot_deg)
                      for p in poses if p.target.status == "ok"}
            if model.tool is not None:
                tool = controller_tool_mm(model.params, model.tool.tool_mm)
        points = program_points(marks, home_deg=home_deg,
                                z2_deg=model.params.z2_deg, joint4=joint4)
        stem = Path(args.out).with_suffix("")
        path = write_program(args.program, program_path(args.program, stem), points, robot,
                             title=f"vision-cal compensated targets: {len(ok)} of {len(planned)} "
                                   f"targets of {args.targets}, {args.model} model",
                             tool_mm=tool)
        if not args.quiet:
            print(f"wrote {path}")
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


def _home_deg(args, doc: dict, robot) -> tuple[float, float]:
    """Where the planned motion starts: ``--home``, else the robot file's ``home_deg``, else
    calibration.json's ``home_deg`` (the session's), else (0, 0)."""
    import math

    from vision_cal.errors import VisionCalError

    if args.home is not None:
        home, where, file = args.home, "--home", None
    elif robot is not None:
        return tuple(robot.nominal.home_deg)
    elif "home_deg" in doc:
        home, where, file = doc["home_deg"], "home_deg", args.calibration
    else:
        return (0.0, 0.0)
    if (not isinstance(home, (list, tuple)) or len(home) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                       and math.isfinite(v) for v in home)):
        raise VisionCalError(f"expected two finite joint angles in degrees, got {home!r}",
                             file=file, field=where)
    return (float(home[0]), float(home[1]))
