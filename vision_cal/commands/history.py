"""``vision-cal history``: a robot's calibrations over time, one table and one plot."""

from __future__ import annotations

from vision_cal.commands import request

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
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.actions.history import HistoryRequest, history

    return history(request(args, HistoryRequest)).show(quiet=args.quiet)
