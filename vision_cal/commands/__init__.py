"""Command-line front end: modules here only parse arguments; the work is in the library.

Each subcommand module defines ``NAME``, ``HELP``, ``add_arguments(parser)`` and
``run(args) -> int``, and is listed in ``main.SUBCOMMANDS``. ``run`` builds the action's
request (:func:`request`), calls one action of ``vision_cal.actions`` and returns what its
outcome's ``show`` returns (the outcome prints itself; the exit code), the action imported
inside ``run`` so that ``--help`` is instant. A
command imports nothing but the actions, this package, errors and progress
(tests/test_architecture.py).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import fields


def request(args, cls):
    """The action's request ``cls`` (a frozen dataclass) from the parsed ``args``: each
    field from the argument of the same name, lists (``nargs``) as tuples."""
    def value(v):
        return tuple(v) if isinstance(v, list) else v

    return cls(**{f.name: value(getattr(args, f.name)) for f in fields(cls)})


def bounded(lo: float | None, hi: float | None, *, integer: bool = False,
            lo_open: bool = False, hi_open: bool = False, unit: str = ""):
    """An argparse ``type`` for a number in ``lo``..``hi`` (``lo_open``/``hi_open``: the end
    excluded; ``unit`` named in the message): anything else, a non-finite number too, is
    one line naming the option, exit 2 (``main._Parser``). Every numeric option of every
    command has one (tests/commands/test_option_bounds.py enumerates them). The range is
    kept on the function (``bounds``) for that test and for ``--help``."""
    kind = "an integer" if integer else "a number"
    u = f" {unit}" if unit else ""

    span = (f"range {'(' if lo_open or lo is None else '['}"
            f"{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}"
            f"{')' if hi_open or hi is None else ']'}{u}")

    def parse(text: str):
        try:
            v = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {kind}, got {text!r}") from None
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"expected a finite number ({span}), got {text}")
        if lo is not None and (v < lo or (lo_open and v == lo)):
            what = ("a non-negative integer" if integer and lo == 0 and not lo_open
                    else f"{'more than' if lo_open else 'at least'} {lo:g}{u}")
            raise argparse.ArgumentTypeError(f"expected {what} ({span}), got {text}")
        if hi is not None and (v > hi or (hi_open and v == hi)):
            what = f"{'less than' if hi_open else 'at most'} {hi:g}{u}"
            raise argparse.ArgumentTypeError(f"expected {what} ({span}), got {text}")
        return v

    parse.bounds = (lo, hi)
    parse.__name__ = "integer" if integer else "number"
    return parse


#: the command line's ranges shared by several commands (the library checks its own)
JOBS = bounded(1, 256, integer=True)               # processes: more adds nothing
SEED = bounded(0, 2**32 - 1, integer=True)         # numpy's seeds: 32 bits are plenty
CAMERA = bounded(0, 99, integer=True)              # calibration.json cameras[] index
HEIGHT_MM = bounded(-10000, 10000, unit="mm")      # a height in a robot's frame
JOINT_DEG = bounded(-720, 720, unit="deg")         # a commanded joint (its limits follow)
