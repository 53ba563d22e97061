"""Pool workers that do not outlive the run that started them.

``kill -9`` of the parent gives it no chance to stop its pool, and a worker busy on a large
photo would otherwise go on for minutes as an orphan. :func:`exit_with_parent` (the pool's
initializer) makes a worker die with its parent:

1. Linux: ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` through ``ctypes``: the kernel kills the
   worker the moment its parent process ends (checked right after, since the parent may
   have died before the call);
2. everywhere: a daemon thread that polls every :data:`POLL_S` seconds whether the run's
   process (``parent_pid``) is still the parent and still alive, and ends the worker with
   ``os._exit`` otherwise (for systems without prctl, and for a fork server in between).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal
import sys
import threading

POLL_S = 0.5
PR_SET_PDEATHSIG = 1


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _set_pdeathsig() -> bool:
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        return libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _watch(parent_pid: int, ppid: int) -> None:
    ev = threading.Event()
    while not ev.wait(POLL_S):
        if os.getppid() != ppid or not _alive(parent_pid):
            os._exit(1)


def exit_with_parent(parent_pid: int) -> None:
    """Pool initializer: end this worker when ``parent_pid`` (the run) ends."""
    ppid = os.getppid()
    _set_pdeathsig()
    if ppid == 1 or not _alive(parent_pid):  # the parent died before prctl took effect
        os._exit(1)
    threading.Thread(target=_watch, args=(parent_pid, ppid), daemon=True,
                     name="exit-with-parent").start()
