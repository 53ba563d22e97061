"""Progress on long work: a tqdm bar on a terminal, one plain line per stage elsewhere.

``progress`` arguments across the package are ``False`` (silent: tests, libraries) or
``True`` (the command line without ``--quiet``). With ``True``, :func:`bar` shows a tqdm bar
when stderr is a terminal; when it is not (CI logs, ``make demo | tee``) it prints a line
when a counted stage starts and one when it ends, with the count and the elapsed time, so
a log shows what is running and where the time went::

    vision-cal: progress: render session: 38 photos (2 job(s)) ...
    vision-cal: progress: render session: 38/38 photos in 91.2 s (0.42 photos/s, 2 job(s))
"""

from __future__ import annotations

import sys
import time

from tqdm import tqdm

PREFIX = "vision-cal: progress: "  # every progress line starts so (errors: "vision-cal: error:")


def _tty() -> bool:
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


class _Line:
    """A stage that reports itself in one line at its end."""

    def __init__(self, desc: str, total: int | None, unit: str, note: str = ""):
        self.desc, self.total, self.unit, self.note = desc, total, unit, note
        self.n = 0
        self.t0 = time.perf_counter()
        self.closed = False
        if total:
            print(f"{PREFIX}{desc}: {total} {unit}s" + (f" ({note})" if note else "")
                  + " ...", file=sys.stderr, flush=True)

    def update(self, n: int = 1) -> None:
        self.n += n

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        stage_line(self.desc, time.perf_counter() - self.t0, n=self.n, total=self.total,
                   unit=self.unit, note=self.note)


class _Off:
    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


def bar(enabled, *, total: int | None, desc: str, unit: str, note: str = ""):
    """An object with ``update(n)`` and ``close()``: a tqdm bar (terminal), a one-line
    stage report (not a terminal) or nothing (``enabled`` false)."""
    if not enabled:
        return _Off()
    if _tty():
        return tqdm(total=total, file=sys.stderr, desc=desc, unit=unit, leave=False)
    return _Line(desc, total, unit, note)


def stage_line(desc: str, seconds: float, *, n: int | None = None, total: int | None = None,
               unit: str = "", note: str = "") -> None:
    """Print ``vision-cal: progress: DESC: N/TOTAL UNITs in S s (rate)`` on stderr."""
    count = ""
    if n is not None:
        count = f"{n}/{total} {unit}s in " if total is not None else f"{n} {unit}s in "
    rate = ""
    if n and seconds >= 0.05:   # a rate over a few milliseconds (all cached) says nothing
        rate = f" ({n / seconds:.2f} {unit}s/s" + (f", {note}" if note else "") + ")"
    elif note:
        rate = f" ({note})"
    print(f"{PREFIX}{desc}: {count}{seconds:.1f} s{rate}", file=sys.stderr, flush=True)
