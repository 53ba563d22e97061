"""``vision-cal init``: the ``images`` list of a session, found from the photos."""

from __future__ import annotations

NAME = "init"
HELP = ("complete a planned session.json with the images list found from a folder of photos "
        "(which marks each photo shows), to check or edit it")
EXAMPLES = """\
examples:
  vision-cal init photos/ --plan plan/session.json -o dataset/session.json
  vision-cal init photos/ --plan plan/session.json > completed.json    (to stdout)

The photo folder is never written: copy the result next to the photos (or point its
images[].file at them) to make a dataset folder. Without an images list, `vision-cal DIR`
does the same inference itself.
"""


def add_arguments(p) -> None:
    p.add_argument("photos", metavar="PHOTOS", help="folder with the photographs")
    p.add_argument("--plan", required=True, metavar="SESSION.json",
                   help="the planned session (no images), e.g. from `vision-cal design`")
    p.add_argument("-o", "--out", default=None, metavar="OUT.json",
                   help="where to write the completed session.json (default: stdout)")
    p.add_argument("-j", "--jobs", type=int, default=None,
                   help="parallel photo measurement (default: the number of cores)")


def run(args) -> int:
    import json
    import sys
    from pathlib import Path

    from vision_cal.dataset.io import atomic_write_json
    from vision_cal.errors import VisionCalError
    from vision_cal.measure.complete import complete_session

    if args.jobs is not None and args.jobs < 1:
        raise VisionCalError(f"--jobs must be at least 1, got {args.jobs}")
    if args.out:
        out = Path(args.out)
        try:
            inside = out.resolve().is_relative_to(Path(args.photos).resolve())
        except (OSError, ValueError) as e:
            raise VisionCalError(f"not a usable path: {e}", file=str(args.out)) from e
        if inside:
            raise VisionCalError("init never writes into the photo folder: write the "
                                 "session elsewhere", file=str(args.out))
        if out.is_dir():
            raise VisionCalError("is a folder, expected a .json file to write",
                                 file=str(args.out))
    progress = (not args.quiet) and sys.stderr.isatty()
    doc, meas = complete_session(args.photos, args.plan, jobs=args.jobs, progress=progress)
    if not doc["images"]:
        raise VisionCalError(f"no usable photo of the sheet among {len(meas.images)} image "
                             "file(s)" + (f" (first: {meas.images[0].file}: "
                                          f"{meas.images[0].reason})" if meas.images else ""),
                             file=str(args.photos))
    for im in meas.images:
        if im.status != "ok":
            print(f"vision-cal: warning: {args.photos}/{im.file}: not used: {im.reason}",
                  file=sys.stderr)
    for w in meas.warnings:
        print(f"vision-cal: warning: {w}", file=sys.stderr)
    if args.out:
        try:
            atomic_write_json(args.out, doc)
        except OSError as e:
            raise VisionCalError(f"cannot write: {e.strerror or e}", file=str(args.out)) from e
    else:
        sys.stdout.write(json.dumps(doc, indent=2) + "\n")
    if not args.quiet:
        n = len(doc["images"])
        print(f"{n} photo(s) of the sheet ({meas.inferred or 'none'}), "
              f"{len(meas.marks)} of {len(meas.marks) + len(meas.refused)} marks found"
              + (f" -> {args.out}" if args.out else ""), file=sys.stderr)
    return 0
