"""kill -9 of a run during measurement does not leave its pool workers alive."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

CHILD = textwrap.dedent("""
    import os, sys, time
    from pathlib import Path
    import numpy as np
    sys.path.insert(0, {root!r})
    from tests.measure import synth_measure as sm
    from vision_cal.measure import detect
    from vision_cal.actions.measure_folder import measure_folder
    from vision_cal.dataset.session import load_session

    src, pids = Path(sys.argv[1]), Path(sys.argv[2])

    def stuck(data, file, session, **kw):    # a photo that takes minutes
        (pids / str(os.getpid())).write_text(file)
        time.sleep(600)

    detect.detect_image_bytes = stuck
    sheet = sm.small_sheet()
    rng = np.random.default_rng(0)
    for k in range(2):
        sm.write_png(src / f"p{{k}}.png", rng.integers(0, 255, (60, 80, 3)).astype(np.uint8))
    sm.write_session(src, sm.session_json(sheet, marks=[("c0", (0.0, 0.0))],
                                          images=[("p0.png", ["c0"]), ("p1.png", ["c0"])]))
    measure_folder(load_session(src), out_dir=src.parent / "out", jobs=2)
""")


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return False
    return "\nState:\tZ" not in state


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_workers_die_with_their_parent(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    pids = tmp_path / "pids"
    pids.mkdir()
    script = tmp_path / "child.py"
    script.write_text(CHILD.format(root=str(ROOT)))
    p = subprocess.Popen([sys.executable, str(script), str(src), str(pids)])
    try:
        t0 = time.monotonic()
        while len(list(pids.iterdir())) < 2:
            assert p.poll() is None, "the run ended before its workers started"
            # a bound against hanging, not a speed limit: two workers start in seconds on an
            # idle machine, far slower on a loaded one
            assert time.monotonic() - t0 < 600, "workers did not start"
            time.sleep(0.1)
        workers = [int(f.name) for f in pids.iterdir()]
        assert all(_alive(w) for w in workers)
        p.send_signal(signal.SIGKILL)
        p.wait()
        # the workers sleep for 120 s (600 s: see CHILD): only dying with their parent ends
        # them sooner; the kernel kills them at once (prctl), a loaded machine may take a
        # while to show it
        t0 = time.monotonic()
        while any(_alive(w) for w in workers) and time.monotonic() - t0 < 60:
            time.sleep(0.1)
        left = [w for w in workers if _alive(w)]
        assert not left, f"orphaned workers still alive: {left}"
    finally:
        if p.poll() is None:
            p.kill()
        for f in pids.iterdir():
            try:
                os.kill(int(f.name), signal.SIGKILL)
            except ProcessLookupError:
                pass
