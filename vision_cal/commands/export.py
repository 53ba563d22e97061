"""``vision-cal export``: a calibration as URDF (plus an effects side file) or YAML."""

from __future__ import annotations

NAME = "export"
HELP = "export calibration.json as URDF joint origins (+ effects side file) or YAML"
EXAMPLES = """\
examples:
  vision-cal fixtures/paper_sm5 --out /tmp/x
  vision-cal export /tmp/x/calibration.json --urdf /tmp/x/robot.urdf
  vision-cal export /tmp/x/calibration.json --yaml /tmp/x/calibration.yaml
"""


def add_arguments(p) -> None:
    p.add_argument("calibration", metavar="CALIBRATION.json", help="the calibration.json to export")
    p.add_argument("--urdf", metavar="ROBOT.urdf", help="URDF with the calibrated joint origins; "
                   "effects go to ROBOT.effects.yaml beside it")
    p.add_argument("--yaml", metavar="FILE.yaml", help="parameters, std and effects as YAML")
    p.add_argument("--robot", metavar="ROBOT.yaml",
                   help="robot file: the URDF's joint limits (default: calibration.json's "
                        "joint_limits_deg, which the session's robot file gave)")
    p.add_argument("--force", action="store_true",
                   help="export even a calibration whose verdict is 'not reliable'")


def run(args) -> int:
    from vision_cal.dataset.calibration import load_calibration
    from vision_cal.dataset.io import distinct_outputs, output_file, written_together
    from vision_cal.errors import VisionCalError
    from vision_cal.report.export import effects_path, export

    if not (args.urdf or args.yaml):
        raise VisionCalError("nothing to export: give --urdf and/or --yaml")
    for opt, path in (("--urdf", args.urdf), ("--yaml", args.yaml)):
        if path:
            output_file(path, field=opt)
    distinct_outputs([("--urdf", args.urdf),
                      ("--urdf (its effects)", args.urdf and effects_path(args.urdf)),
                      ("--yaml", args.yaml)], [("CALIBRATION.json", args.calibration)])
    _, doc = load_calibration(args.calibration)
    from vision_cal.dataset.trust import refuse_unreliable

    warn = refuse_unreliable(doc, args.calibration, force=args.force)
    if warn:
        import sys

        print(warn, file=sys.stderr)
    limits = doc.get("joint_limits_deg")
    if args.robot:
        from vision_cal.dataset.robot import load_robot_file

        limits = load_robot_file(args.robot).joint_limits_deg
    with written_together():
        written = export(doc, urdf=args.urdf, yaml_path=args.yaml, limits_deg=limits)
    for path in written:
        if not args.quiet:
            print(f"wrote {path}")
    return 0
