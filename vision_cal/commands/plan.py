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
    p.add_argument("calibration", metavar="CALIBRATION.json", help="the calibration.json to plan with")
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
    p.add_argument("--force", action="store_true",
                   help="plan even with a calibration whose verdict is 'not reliable'")
    p.add_argument("--approach4", type=int, choices=(1, -1), default=1,
                   help="approach sign of joint 4 when the plan turns it (default: 1)")


def run(args) -> int:
    import math
    import sys
    from pathlib import Path

    from vision_cal.dataset.calibration import load_calibration
    from vision_cal.dataset.csvio import (failed_report_path, read_target_theta, read_targets,
                                          write_failed_targets, write_plan)
    from vision_cal.dataset.io import distinct_outputs, output_file, written_together
    from vision_cal.errors import VisionCalError
    from vision_cal.plan.compensate import plan_targets
    from vision_cal.plan.uncertainty import load_covariance, predicted_std_mm

    output_file(args.out, field="-o")
    if args.trajectory:
        output_file(args.trajectory, field="--trajectory")
    prg = None
    if args.program:
        from vision_cal.program import program_path

        prg = program_path(args.program, Path(args.out).with_suffix(""))
        output_file(prg, field="--program")
    report = failed_report_path(args.out)
    distinct_outputs([("-o", args.out), ("-o (its failed targets)", report),
                      ("--trajectory", args.trajectory), ("--program", prg)],
                     [("CALIBRATION.json", args.calibration), ("TARGETS.csv", args.targets),
                      ("--robot", args.robot)])
    robot = None
    if args.program and not args.robot:
        raise VisionCalError("--program needs --robot ROBOT.yaml (pen heights, speeds)",
                             field="--robot")
    if args.robot:
        from vision_cal.dataset.robot import load_robot_file

        robot = load_robot_file(args.robot)
        if args.program:
            robot.require_pen_heights()
    model, doc = load_calibration(args.calibration, which=args.model)
    from vision_cal.dataset.trust import refuse_unreliable

    warn = refuse_unreliable(doc, args.calibration, force=args.force)
    if warn:
        print(warn, file=sys.stderr)
    home_deg = _home_deg(args, doc, robot)
    ids, xy = read_targets(args.targets)
    if args.trajectory:  # a million targets: refused before they are planned
        from vision_cal.plan.trajectory import check_length

        try:
            check_length(len(ids))
        except VisionCalError as e:
            raise VisionCalError(e.reason, file=str(args.trajectory),
                                 field="--trajectory") from e
    limits = {} if robot is None else {"joint_limits_deg": robot.joint_limits_deg}
    if robot is None and doc.get("joint_limits_deg") is not None:   # recorded by the run
        limits = {"joint_limits_deg": tuple(tuple(float(v) for v in p)
                                            for p in doc["joint_limits_deg"])}
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
    # every output is written together or not at all (a program path that cannot be
    # written, a trajectory too long, leave the earlier files as they were)
    with written_together():
        # the command file holds only what can be sent to the robot: no NaN, no failed row
        # (an unknown std, as with the nominal model, is left empty)
        write_plan(args.out, [dict(p.to_row() if poses is None else pose_of[p.id].to_row(),
                                   std_mm=float(s) if math.isfinite(s) else "")
                              for p, s in zip(ok, std)])
        if failed:
            write_failed_targets(report, [(p.id, *p.target_mm, p.reason) for p in failed])
        if args.trajectory and ok:
            from vision_cal.plan.compensate import write_plan_trajectory

            try:
                write_plan_trajectory(args.trajectory, ok, home_deg=home_deg)
            except VisionCalError as e:
                raise VisionCalError(e.reason, file=str(args.trajectory),
                                     field="--trajectory") from e
        if args.program and ok:  # no program of nothing (exit 1 below)
            from vision_cal.plan.compensate import to_planned_marks
            from vision_cal.program import program_points, write_program

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
            path = write_program(args.program, prg, points, robot,
                                 title=f"vision-cal compensated targets: {len(ok)} of "
                                       f"{len(planned)} targets of {args.targets}, "
                                       f"{args.model} model", tool_mm=tool)
            if not args.quiet:
                print(f"wrote {path}")
    if failed:
        if ok:  # when none is planned, the error below says it once
            print(f"vision-cal: warning: {args.targets}: {summarise_failures(failed)}; "
                  f"all in {report}", file=sys.stderr)
    else:
        report.unlink(missing_ok=True)  # a stale report of an earlier run
    _say_targets_on_print(args, doc, ok)
    if not args.quiet:
        print(f"planned {len(planned) - len(failed)} of {len(planned)} targets "
              f"with the {args.model} model -> {args.out}")
    if not ok:
        print(f"vision-cal: error: {args.targets}: nothing could be planned with the "
              f"{args.model} model of {args.calibration}: {summarise_failures(failed)}; "
              f"all in {report}", file=sys.stderr)
        return 1
    return 0


def _say_targets_on_print(args, doc: dict, ok) -> None:
    """One warning line naming the planned targets that lie on the sheet's printed ink
    (calibration.json ``printed_content``) and what it costs."""
    import sys

    from vision_cal.measure.printed import targets_on_print

    content = doc.get("printed_content") or []
    if not content or not ok:
        return
    on = targets_on_print(content, [p.id for p in ok], [p.target_mm for p in ok], 1.0)
    if not on:
        return
    head = "; ".join(f"{tid} ({', '.join(labels)})" for tid, labels in on[:3])
    more = f" and {len(on) - 3} more" if len(on) > 3 else ""
    print(f"vision-cal: warning: {args.targets}: {len(on)} target(s) on the sheet's printed "
          f"ink: {head}{more}: a pen mark there is measured against the print (0.01-0.02 mm "
          "less certain) or, where it cannot be separated, left out as unreliable; move the "
          "target by a few millimetres onto plain paper to check it", file=sys.stderr)


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
        from vision_cal.motion import JOINT_LIMITS_DEG

        lims = JOINT_LIMITS_DEG if robot is None else robot.joint_limits_deg
        of = "the default joint limits" if robot is None else f"joint_limits_deg of {args.robot}"
        for j in range(2):
            if not (math.isfinite(home[j]) and lims[j][0] <= home[j] <= lims[j][1]):
                raise VisionCalError(f"joint {j + 1} at {home[j]:g} deg is outside {of} "
                                     f"{list(lims[j])}", field="--home")
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
