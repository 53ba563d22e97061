"""``vision-cal``: calibrate a SCARA robot from photographs of the sheet it drew on.

Exit codes: 0 done (skipped photos are warnings); 1 could not calibrate (too few usable
marks, an unidentifiable plan) or plan; 2 bad arguments or dataset; 3 planned (located) in
part: the targets not planned are listed with the reason.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import re
import sys

SUBCOMMANDS = ("calibrate", "sheet", "design", "init", "render", "plan", "loop", "export",
               "simulate", "verify", "robot-template", "history", "locate", "handeye",
               "survey")
EXIT_OK, EXIT_CALIBRATION, EXIT_INPUT = 0, 1, 2

EPILOG = """\
exit codes:
  0  done (skipped photos are warnings)
  1  could not calibrate (too few usable marks, unidentifiable plan)
  2  bad arguments or dataset
  3  planned (located) in part: plan and locate --csv list each target not planned
     with the reason and what would cover it (PLAN.failed.csv, locate's status column)

examples:
  vision-cal images/ --report              calibrate a folder (calibrate is the default)
  vision-cal fixtures/paper_sm5 --method paper --out /tmp/x
  vision-cal render renders/default.yaml --out /tmp/d
"""


def _module(name: str):
    return importlib.import_module(f"vision_cal.commands.{name.replace('-', '_')}")


class _Parser(argparse.ArgumentParser):
    """A bad option is one line naming it (argparse prints the whole usage first, eight
    lines for `plan`), with where the usage is."""

    def error(self, message):
        # "argument -j/--jobs: expected ..." -> "--jobs: expected ...": the option first, as
        # every error line names its file or option
        message = re.sub(r"^argument ([^:\s]+): ",
                         lambda m: m.group(1).split("/")[-1] + ": ", message)
        self.exit(EXIT_INPUT, f"{self.prog}: error: {message} (usage: {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    from vision_cal import __version__

    parser = _Parser(
        prog="vision-cal", description=__doc__.splitlines()[0].split(": ", 1)[1],
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"vision-cal {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMANDS:
        mod = _module(name)  # an import error is a bug: never hide a command
        p = sub.add_parser(name, help=mod.HELP, description=mod.HELP,
                           epilog=getattr(mod, "EXAMPLES", None),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        add_common(p)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def add_common(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("output")
    g.add_argument("-q", "--quiet", action="store_true", help="no progress bars or summary")
    g.add_argument("-v", "--verbose", action="store_true", help="log details; tracebacks on error")


class _LowerLevelFormatter(logging.Formatter):
    def format(self, record):
        record = logging.makeLogRecord(record.__dict__)
        record.levelname = record.levelname.lower()
        return super().format(record)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    # `calibrate` is the default when the first argument is not a subcommand or option
    if argv and argv[0] not in SUBCOMMANDS and not argv[0].startswith("-"):
        argv.insert(0, "calibrate")
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return EXIT_INPUT
    # one spelling on stderr: "vision-cal: warning: ..." (the commands' own lines) and the
    # log's alike (logging's level names are upper case)
    handler = logging.StreamHandler()
    handler.setFormatter(_LowerLevelFormatter("vision-cal: %(levelname)s: %(message)s"))
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING,
                        handlers=[handler])
    from vision_cal.errors import CalibrationError, VisionCalError

    try:
        return int(args._run(args) or 0)
    except CalibrationError as e:
        if args.verbose:
            raise
        print(f"vision-cal: error: {e}", file=sys.stderr)
        return EXIT_CALIBRATION
    except VisionCalError as e:
        if args.verbose:
            raise
        print(f"vision-cal: error: {e}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:
        print("vision-cal: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
