"""``vision-cal calibrate``: measure and calibrate dataset folders."""

from __future__ import annotations

NAME = "calibrate"
HELP = "measure the photographs of a dataset folder and calibrate the robot"
EXAMPLES = """\
examples:
  vision-cal fixtures/paper_sm5 --out /tmp/x               least squares (default)
  vision-cal fixtures/paper_sm5 --method paper --out /tmp/x  the seed paper's circles
  vision-cal images/ --out out/ --jobs 2                   photographs, in parallel
"""


def add_arguments(p) -> None:
    p.add_argument("folders", nargs="+", metavar="DIR", help="dataset folder(s) with session.json")
    p.add_argument("-o", "--out", default=None,
                   help="output folder (default: out/<folder name>); with several folders, "
                        "one sub-folder each")
    p.add_argument("--method", choices=("lsq", "paper"), default="lsq",
                   help="lsq: least squares with effect diagnosis (default); paper: the seed "
                        "paper's three-point circles")
    p.add_argument("-j", "--jobs", type=int, default=None, help="parallel photo measurement "
                   "(default: the number of cores)")
    p.add_argument("--truth", action="store_true",
                   help="compare with truth.json (synthetic data only)")
    p.add_argument("--report", action="store_true", help="also write report.json and report.html")


def run(args) -> int:
    import sys
    from pathlib import Path

    from vision_cal.dataset.io import read_json
    from vision_cal.errors import VisionCalError
    from vision_cal.pipeline import calibrate_dataset
    from vision_cal.report.summary import format_summary

    if args.jobs is not None and args.jobs < 1:
        raise VisionCalError(f"--jobs must be at least 1, got {args.jobs}")
    progress = (not args.quiet) and sys.stderr.isatty()
    several = len(args.folders) > 1
    failures = 0
    for folder in args.folders:
        name = Path(folder).resolve().name
        out = Path(args.out) / name if (args.out and several) else Path(args.out or f"out/{name}")
        try:
            result = calibrate_dataset(folder, out_dir=out, method=args.method, jobs=args.jobs,
                                       progress=progress, truth=args.truth)
        except VisionCalError as e:
            if not several:
                raise
            failures += 1
            print(f"vision-cal: error: {folder}: {e}", file=sys.stderr)
            continue
        if not args.quiet:
            ref = result.session.raw.get("reference")
            print(format_summary(result.document, reference=ref))
        for im in result.document.get("images", []):
            if im.get("status") != "ok":
                print(f"vision-cal: warning: {folder}/{im['file']}: skipped: {im.get('reason')}",
                      file=sys.stderr)
        if args.report:
            from vision_cal.report.html import write_report

            path = write_report(result, out)
            print(f"report: {path}")
        print(f"wrote {result.out_path}")
    return 1 if failures else 0
