"""What several outcomes say the same way. Each action returns a typed outcome that prints
itself: its ``show(quiet=...)`` method, beside its class in the action's module, prints the
command's lines (stdout; warnings on stderr) and returns the command's exit code. The
actions write files and print nothing of their results while they run (progress bars and
the output folder's notices aside); a long action tells each step's outcome as it happens
to a callback the command points at the outcome's ``show`` (``calibrate``: each folder, as
soon as it is done)."""

from __future__ import annotations

import sys
from typing import Iterable, Protocol

from vision_cal.estimate.verdict import Verdict
from vision_cal.report.summary import verdict_lines as _summary_verdict_lines


class Outcome(Protocol):
    """What an action returns (or tells as it goes): it prints itself."""

    def show(self, quiet: bool = False) -> int:
        """Print the command's lines (nothing but warnings and what a quiet run still says,
        when ``quiet``); the command's exit code."""


def say(lines: Iterable[str]) -> None:
    """Each of ``lines`` on stdout."""
    for line in lines:
        print(line)


def warn(text: str) -> None:
    """One warning line on stderr (said even when quiet)."""
    print(f"vision-cal: warning: {text}", file=sys.stderr)


def error(text: str) -> None:
    """One error line on stderr (said even when quiet)."""
    print(f"vision-cal: error: {text}", file=sys.stderr)


def verdict_and_written(doc_verdict: dict, path) -> list[str]:
    """A camera calibration's closing lines: its verdict (calibration.json ``verdict``) with
    the floor line first, then the file written."""
    v = Verdict.from_json(doc_verdict)
    return ([v.floor_line] if v.floor_line else []) + verdict_lines(v) + [f"wrote {path}"]


def verdict_lines(v) -> list[str]:
    """A :class:`~vision_cal.estimate.verdict.Verdict` as the console's lines (one reason a
    line: :func:`vision_cal.report.summary.verdict_lines`)."""
    return _summary_verdict_lines({**v.to_json(), "text": v.text})
