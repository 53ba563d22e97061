"""``vision-cal loop``: the closed loop on a synthetic scene, before and after."""

from __future__ import annotations

NAME = "loop"
HELP = ("render a calibration session, calibrate it from the photos, plan targets with the "
        "nominal and calibrated models, draw them with the true robot, photograph and measure")
EXAMPLES = """\
examples:
  vision-cal loop renders/default.yaml --out out/demo        (what `make demo` runs)
  vision-cal loop renders/small.yaml --out /tmp/loop --jobs 2
"""


def add_arguments(p) -> None:
    p.add_argument("scene", metavar="SCENE.yaml", help="scene file (see renders/README.md)")
    p.add_argument("-o", "--out", required=True, metavar="DIR",
                   help="folder for the rendered sessions, the calibration, loop.json")
    p.add_argument("-j", "--jobs", type=int, default=None,
                   help="processes that render and measure photos (default: every core)")
    p.add_argument("--elbow", type=int, choices=(1, -1), default=1,
                   help="elbow of the planned targets (+1: sin(q2 + z2) > 0; default 1)")
    p.add_argument("--no-report", dest="report", action="store_false",
                   help="skip DIR/calibration/report.html (written by default)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the library pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from pathlib import Path

    from vision_cal.workflows.loop import format_table, run_loop
    from vision_cal.report.summary import format_summary

    if args.jobs is not None and args.jobs < 1:
        from vision_cal.errors import VisionCalError

        raise VisionCalError(f"must be at least 1, got {args.jobs}", field="--jobs")
    progress = not args.quiet  # a bar on a terminal, else one line per stage
    from vision_cal.dataset.out_folder import writing_into

    with writing_into(args.out, command="loop", retire=False):   # locked while written
        doc, run = run_loop(args.scene, out_dir=args.out, jobs=args.jobs, progress=progress,
                            elbow=args.elbow)
    if not args.quiet:
        print(format_summary(run.document))
        print()
        print("absolute error of each target, measured from the photographs (Table 3):")
        print(format_table(doc))
    if args.report:
        from vision_cal.report.html import write_report

        path = write_report(run.out_path, Path(args.out) / "calibration",
                            loop=Path(args.out) / "loop.json")
        print(f"report: {path.resolve()} ({path.stat().st_size / 1e6:.1f} MB; the photos it "
              f"links are in {Path(args.out).resolve()})")
    return 0
