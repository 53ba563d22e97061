"""``vision-cal history``: a robot's calibrations over time, one table and one plot."""

from __future__ import annotations

NAME = "history"
HELP = ("a robot's calibrations over time: every calibration.json under a folder as one "
        "table (each parameter with its std, by date) and a plot")
EXAMPLES = """\
examples:
  vision-cal history calibrations/              print the table
  vision-cal history calibrations/ -o history.csv --plot history.png

Each calibration is dated by the report.json beside it (written with --report), else by
the file's modification time (the table says which).
"""


def add_arguments(p) -> None:
    p.add_argument("folder", metavar="FOLDER", help="a folder holding calibration.json files "
                                                    "(in subfolders, e.g. one per date)")
    p.add_argument("-o", "--out", metavar="CSV", help="also write the table as CSV")
    p.add_argument("--plot", metavar="PNG", help="also write the plot (each parameter +- std "
                                                 "by date)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the library pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.dataset.io import atomic_write_bytes, atomic_write_text, written_together
    from vision_cal.dataset.out_folder import output_file_of_kind
    from vision_cal.report.history import history_csv, history_png, history_table, read_history

    # an output on a calibration.json, on another output or on a file of another kind is
    # refused before anything is read or written (issue 30)
    if args.out:
        output_file_of_kind(args.out, "csv", field="-o")
    if args.plot:
        output_file_of_kind(args.plot, "png", field="--plot", outputs=[("-o", args.out)])
    rows = read_history(args.folder)
    csv_text = history_csv(rows)
    png = history_png(rows) if args.plot else None
    with written_together():
        if args.out:
            atomic_write_text(args.out, csv_text)
        if png is not None:
            atomic_write_bytes(args.plot, png)
    if not args.quiet:
        print(history_table(rows))
        for p in (args.out, args.plot):
            if p:
                print(f"wrote {p}")
    return 0
