"""Command-line front end: modules here only parse arguments; the work is in the library.

Each subcommand module defines ``NAME``, ``HELP``, ``add_arguments(parser)`` and
``run(args) -> int``, and is listed in ``main.SUBCOMMANDS``. ``run`` calls one action
(``vision_cal.actions`` or a stage module's entry point), imported inside ``run`` so that
``--help`` is instant.
"""

from __future__ import annotations

from dataclasses import fields


def request(args, cls):
    """The action's request ``cls`` (a frozen dataclass) from the parsed ``args``: each
    field from the argument of the same name, lists (``nargs``) as tuples."""
    def value(v):
        return tuple(v) if isinstance(v, list) else v

    return cls(**{f.name: value(getattr(args, f.name)) for f in fields(cls)})
