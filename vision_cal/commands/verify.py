"""``vision-cal verify``: is the robot still calibrated? A short check against calibration.json."""

from __future__ import annotations

NAME = "verify"
HELP = ("check a calibration on a short plan drawn later (design --verify): each mark's error, "
        "which parameters moved (with std) and a verdict: still good, re-zero a joint, or "
        "recalibrate")
EXAMPLES = """\
examples:
  vision-cal design robot.yaml --sheet sheet/sheet.json --verify cal/calibration.json --out check/
      about ten marks across the workspace, both elbows (draw them on a fresh sheet,
      photograph it into check/)
  vision-cal verify cal/calibration.json check/
      -> check_verify/verify.json and the verdict

The sheet's placement (base x, y and z1, which includes the robot's rotation to the sheet)
is refitted first: a new sheet lies elsewhere, so joint 1's zero cannot be checked on it.
Exit code 0 whatever the verdict (read it, or verify.json's "verdict").
"""


def add_arguments(p) -> None:
    p.add_argument("calibration", metavar="CAL.json", help="the calibration.json to check")
    p.add_argument("folder", metavar="PHOTOS/",
                   help="the check's folder: session.json from design --verify and the photos")
    p.add_argument("-o", "--out", metavar="DIR", default=None,
                   help="folder for verify.json and the measurement cache (default: "
                        "PHOTOS_verify beside the photos; the photos' folder is never written)")
    p.add_argument("--force", action="store_true",
                   help="check even marks outside what the calibration was calibrated for "
                        "(calibration.json valid_for: joint ranges, approach sides, joint 4), "
                        "the extrapolation stated in verify.json and on the console")
    p.add_argument("-j", "--jobs", type=int, default=None, metavar="N",
                   help="processes that measure photos (default: every core)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the library pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    import sys
    from pathlib import Path

    from vision_cal.dataset.out_folder import writing_into
    from vision_cal.errors import VisionCalError
    from vision_cal.workflows.verify import verify_folder

    if args.jobs is not None and args.jobs < 1:
        raise VisionCalError(f"must be at least 1, got {args.jobs}", field="--jobs")
    folder = Path(args.folder)
    here = folder.resolve()
    out = Path(args.out) if args.out else here.with_name(here.name + "_verify")
    # the output folder: never the photos' folder nor the one holding CAL.json; an earlier
    # check's results go to previous/; locked while written (issue 30)
    with writing_into(out, command="verify", field="-o",
                      inputs=[("CAL.json", args.calibration), ("PHOTOS/", args.folder)],
                      quiet=args.quiet) as out:
        r, path, said = verify_folder(args.calibration, folder, out_dir=out, jobs=args.jobs,
                                      progress=not args.quiet, force=args.force)
    for w in said:   # --force: the check compared beyond what was calibrated
        print(f"vision-cal: warning: {w}", file=sys.stderr)
    if not args.quiet:
        print(f"{'mark':<8}{'error x':>10}{'error y':>10}{'|error|':>10}  [mm, the sheet's "
              "placement taken out]")
        for mid, m in r.marks.items():
            ex, ey = m["error_mm"]
            print(f"{mid:<8}{ex:>+10.4f}{ey:>+10.4f}{m['error_norm_mm']:>10.4f}")
        print(f"RMS {r.rms_mm['sheet_placed']:.4f} mm (bound for 'still good': "
              f"{r.bound_mm:.4f} mm)")
        print(f"{'parameter':<12}{'change':>10}{'std':>9}  moved?")
        for label, c in r.changes.items():
            if c.get("sheet_placement"):
                continue
            print(f"{label:<12}{c['delta']:>+10.4f}{c['std']:>9.4f}  "
                  f"{'yes' if c['moved'] else 'no'} ({c['sigmas']:.1f} std)")
        if r.iso9283:
            print("ISO 9283 (each visit's own commanded point taken out; assumes the robot's "
                  "error is the same over each point's few-mm grid of visits):")
            for name, v in r.iso9283.items():
                print(f"  {name}: AP {v['AP_mm']:.4f} mm, RP {v['RP_mm']:.4f} mm "
                      f"({v['n']} visits)")
        print(f"verdict: {r.verdict}")
        for reason in r.reasons:
            print(f"  {reason}")
        print(f"wrote {path}")
    return 0
