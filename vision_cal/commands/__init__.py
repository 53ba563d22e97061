"""Command-line front end: modules here only parse arguments; the work is in the library.

Each subcommand module defines ``NAME``, ``HELP``, ``add_arguments(parser)`` and
``run(args) -> int``, and is listed in ``main.SUBCOMMANDS``. Heavy imports happen inside
``run`` so ``--help`` is instant.
"""
