"""Cost of calibration against the number of marks: time and peak memory for 40, 400, 4,000
and 20,000 marks (issue 19: the sheet-map permutation tests once built an N x N matrix per
permutation).

Each size runs in a fresh Python process (so peak memory, ``tracemalloc`` over numpy's
allocations in a second run of each step and ``ru_maxrss``, is its own; the time is of the
first, untraced run) on marks of the SM5-like truth drawn with the
bench's pose spread and 12 um noise (seed 7: not a seed any test uses), and times:

- ``sheet_scan``: the k-nearest-neighbour sheet map with its 999 permutations
  (``estimate/structure.py``);
- ``smooth_residual``: the smooth-residual test with its 1999 permutations
  (``estimate/sheet.py``);
- ``diagnose``: the whole effect selection (base fit, candidates, k-fold held-out RMS,
  periodogram, sheet map), i.e. the calibration after measurement.

Linear means: time and memory per mark roughly constant from 4,000 to 20,000 marks.

Usage::

    .venv/bin/python bench/marks_scaling.py [--sizes 40 400 4000 20000] [--no-diagnose]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

CHILD = "--child"
ROOT = Path(__file__).resolve().parents[1]


def marks(n: int, seed: int = 7):
    from vision_cal.world.truth_model import TrueRobot

    rng = np.random.default_rng(seed)
    truth = TrueRobot(344.05, 259.87, (-2.57, -8.13), (-424.26, -230.35))
    q = np.column_stack([rng.uniform(-80, 40, n), rng.uniform(-140, 140, n)])
    s = rng.choice([-1.0, 1.0], size=(n, 2))
    xy = truth.pen_mm(q, s) + rng.normal(0, 0.012, (n, 2))
    return q, s, xy


def child(n: int, with_diagnose: bool) -> dict:
    from vision_cal.estimate.select import diagnose
    from vision_cal.estimate.sheet import smooth_residual
    from vision_cal.estimate.structure import sheet_scan

    q, s, xy = marks(n)
    out = {"marks": n}
    res = np.random.default_rng(8).normal(0, 0.012, (n, 2))
    ext = (*xy.min(axis=0), *xy.max(axis=0))
    steps = [("sheet_scan", lambda: sheet_scan(xy, res)),
             ("smooth_residual", lambda: smooth_residual(xy, res, ext))]
    if with_diagnose:
        steps.append(("diagnose", lambda: diagnose(q, xy, s)))
    for name, f in steps:
        t0 = time.perf_counter()  # timed on its own: tracing slows numpy's allocations
        f()
        out[f"{name}_s"] = time.perf_counter() - t0
        tracemalloc.start()
        f()
        out[f"{name}_peak_mb"] = tracemalloc.get_traced_memory()[1] / 1e6
        tracemalloc.stop()
    out["max_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[40, 400, 4000, 20000])
    ap.add_argument("--no-diagnose", action="store_true")
    ap.add_argument(CHILD, type=int, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child is not None:
        print(json.dumps(child(a.child, not a.no_diagnose)))
        return
    cols = ["sheet_scan", "smooth_residual"] + ([] if a.no_diagnose else ["diagnose"])
    head = f"{'marks':>6} " + " ".join(f"{c + ' s':>18} {'MB':>7}" for c in cols) + \
        f" {'max RSS MB':>10}"
    print(head)
    for n in a.sizes:
        argv = [sys.executable, __file__, CHILD, str(n)] + (["--no-diagnose"] if a.no_diagnose
                                                             else [])
        # the child imports this checkout's vision_cal, whatever the venv has installed
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))
        r = json.loads(subprocess.run(argv, check=True, capture_output=True, text=True,
                                      env=env).stdout.strip().splitlines()[-1])
        print(f"{n:>6} " + " ".join(f"{r[c + '_s']:>18.2f} {r[c + '_peak_mb']:>7.1f}"
                                    for c in cols) + f" {r['max_rss_mb']:>10.0f}", flush=True)


if __name__ == "__main__":
    main()
