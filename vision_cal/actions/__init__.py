"""What each ``vision-cal`` subcommand does (OpenSfM-style actions): ``commands/`` parse the
arguments into an action's request (a frozen dataclass) and call one function here, which
does the work and returns a typed outcome; :mod:`vision_cal.actions.console` prints it (the
one place results are printed). A few actions still print their own results and return an
exit code (``PRINTS_PENDING`` in tests/test_architecture.py)."""
