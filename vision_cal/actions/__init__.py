"""What each ``vision-cal`` subcommand does (OpenSfM-style actions): ``commands/`` parse the
arguments into an action's request (a frozen dataclass) and call one function here, which
does the work and returns a typed outcome that prints itself: its ``show(quiet=...)`` method,
beside its class, prints the command's lines and returns the exit code
(:mod:`vision_cal.actions.console`: what several outcomes say the same way)."""
