"""What each ``vision-cal`` subcommand does (OpenSfM-style actions): ``commands/`` parse the
arguments and call one function here (or a stage module's entry point), which does the
work and prints to the console."""
