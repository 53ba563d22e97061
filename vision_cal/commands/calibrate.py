"""``vision-cal calibrate``: measure and calibrate dataset folders."""

from __future__ import annotations

NAME = "calibrate"
HELP = "measure the photographs of a dataset folder and calibrate the robot"
EXAMPLES = """\
examples:
  vision-cal fixtures/paper_sm5 --out /tmp/x               least squares (default)
  vision-cal fixtures/paper_sm5 --method paper --out /tmp/x  the seed paper's circles
  vision-cal images/ --out out/ --jobs 2                   photographs, in parallel
  vision-cal calibrate A/ B/ C/ --joint --out X/           one robot, three placements
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
    p.add_argument("--joint", action="store_true",
                   help="the folders are placements of one sheet (or several sheets) drawn by "
                        "one robot: fit one robot and one sheet pose each (robot frame R; "
                        "OUT/calibration.json, OUT/<folder>/calibration.json)")


def run(args) -> int:
    import sys
    from pathlib import Path

    from vision_cal.dataset.io import output_dir
    from vision_cal.errors import VisionCalError
    from vision_cal.pipeline import calibrate_dataset
    from vision_cal.report.summary import format_summary

    if args.jobs is not None and args.jobs < 1:
        raise VisionCalError(f"--jobs must be at least 1, got {args.jobs}")
    progress = not args.quiet  # a bar on a terminal, else one line per stage
    if args.joint:   # one robot from several placements (calibrate/placements.py)
        from vision_cal.calibrate.placements import calibrate_placements

        if args.method != "lsq":
            raise VisionCalError("--joint fits by least squares only", field="--method")
        out = Path(args.out or "out")
        output_dir(out, field="--out")
        doc = calibrate_placements(args.folders, out_dir=out, jobs=args.jobs,
                                   progress=progress)
        if not args.quiet:
            for pl in doc["placements"]:
                print(f"{pl['folder']}: sheet at {pl['angle_deg']:.3f} deg, base "
                      f"({pl['base_mm'][0]:.3f}, {pl['base_mm'][1]:.3f}) mm, rms "
                      f"{pl['residual_rms_mm']:.4f} mm")
            print("effects: " + (", ".join(e["name"] + f"(joint {e['joint']})"
                                           for e in doc["effects"]) or "none"))
        print(f"wrote {out / 'calibration.json'}")
        return 0
    several = len(args.folders) > 1
    output_dir(args.out or "out", field="--out")
    from vision_cal.dataset.out_folder import output_names, retire_earlier_run

    names = output_names(args.folders)
    if several and not args.quiet:
        plain = [Path(f).resolve().name for f in args.folders]
        if names != plain:  # two folders share a name: say where each one goes
            print("outputs: " + ", ".join(f"{f} -> {Path(args.out or 'out') / n}"
                                          for f, n in zip(args.folders, names)))
    failures = 0
    rows = []
    for folder, name in zip(args.folders, names):
        out = Path(args.out) / name if (args.out and several) else Path(args.out or f"out/{name}")
        try:
            # OUT holds one run: an earlier run's results go to OUT/previous/ first, so a
            # failed or interrupted run leaves nothing that looks current
            moved = retire_earlier_run(out)
            if moved and not args.quiet:
                print(f"moved the earlier results ({', '.join(moved)}) to {out / 'previous'}")
            result = calibrate_dataset(folder, out_dir=out, method=args.method, jobs=args.jobs,
                                       progress=progress, truth=args.truth)
        except VisionCalError as e:
            if not several:
                raise
            failures += 1
            print(f"vision-cal: error: {folder}: {e}", file=sys.stderr)
            rows.append({"folder": str(folder), "status": "failed", "reason": str(e)})
            continue
        d = result.document
        rows.append({"folder": str(folder), "status": "ok", "out": str(result.out_path),
                     "marks": len(d["marks"]),
                     "skipped_photos": sum(im.get("status") != "ok" for im in d["images"]),
                     "effects": [e["name"] + (f"(joint {e['joint']})" if "joint" in e else "")
                                 for e in d["effects"]],
                     "residual_rms_mm": d["residual_rms_mm"]["final_model"],
                     "validation_rms_mm": d["validation_rms_mm"]["final_model"]})
        if not args.quiet:
            ref = result.session.raw.get("reference")
            print(format_summary(result.document, reference=ref))
        for im in result.document.get("images", []):
            if im.get("status") != "ok":
                print(f"vision-cal: warning: {folder}/{im['file']}: skipped: {im.get('reason')}",
                      file=sys.stderr)
        meas = getattr(result, "measurement", None)
        for note in getattr(meas, "inferred_notes", ()):  # no images list: what looked odd
            print(f"vision-cal: warning: {folder}: {note}", file=sys.stderr)
        if args.report:
            from vision_cal.report.html import write_report

            try:
                path = write_report(result.out_path, out)
            except BaseException:  # Ctrl-C or a failure: both report files or neither
                for n in ("report.json", "report.html"):
                    (out / n).unlink(missing_ok=True)
                raise
            print(f"report: {path} ({path.stat().st_size / 1e6:.1f} MB)")
        print(f"wrote {result.out_path}")
    if several:
        from vision_cal.dataset.io import atomic_write_json

        root = Path(args.out or "out")
        atomic_write_json(root / "summary.json", {"folders": rows})
        print(_summary_table(rows))
        print(f"wrote {root / 'summary.json'}")
    return 1 if failures else 0


def _summary_table(rows) -> str:
    def f(x):
        return "-" if x is None else f"{x:.4f}"

    lines = [f"{'folder':<28}{'status':<8}{'marks':>6}{'skipped':>8}{'rms [mm]':>10}"
             f"{'held-out':>10}  effects"]
    for r in rows:
        if r["status"] != "ok":
            lines.append(f"{r['folder'][-28:]:<28}{'failed':<8}  {r['reason']}")
            continue
        lines.append(f"{r['folder'][-28:]:<28}{'ok':<8}{r['marks']:>6}{r['skipped_photos']:>8}"
                     f"{f(r['residual_rms_mm']):>10}{f(r['validation_rms_mm']):>10}  "
                     f"{', '.join(r['effects']) or 'none'}")
    return "\n".join(lines)
