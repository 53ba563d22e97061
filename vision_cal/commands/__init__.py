"""Command-line front end: modules here only parse arguments; the work is in the library.

Each subcommand module defines ``NAME``, ``HELP``, ``add_arguments(parser)`` and
``run(args) -> int``, and is listed in ``main.SUBCOMMANDS``. ``run`` builds the action's
request (:func:`request`), calls one action of ``vision_cal.actions`` and hands its outcome to
``actions.console.show``; both imported inside ``run`` so that ``--help`` is instant. A
command imports nothing but the actions, this package, errors and progress
(tests/test_architecture.py).
"""

from __future__ import annotations

from dataclasses import fields


def request(args, cls):
    """The action's request ``cls`` (a frozen dataclass) from the parsed ``args``: each
    field from the argument of the same name, lists (``nargs``) as tuples."""
    def value(v):
        return tuple(v) if isinstance(v, list) else v

    return cls(**{f.name: value(getattr(args, f.name)) for f in fields(cls)})
