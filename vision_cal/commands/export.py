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
    p.add_argument("calibration", metavar="CALIBRATION.json")
    p.add_argument("--urdf", metavar="ROBOT.urdf", help="URDF with the calibrated joint origins; "
                   "effects go to ROBOT.effects.yaml beside it")
    p.add_argument("--yaml", metavar="FILE.yaml", help="parameters, std and effects as YAML")


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
    with written_together():
        written = export(doc, urdf=args.urdf, yaml_path=args.yaml)
    for path in written:
        if not args.quiet:
            print(f"wrote {path}")
    return 0
