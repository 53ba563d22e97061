"""Time of each stage of the closed loop on the default scene, and planner throughput.

Usage: .venv/bin/python bench/loop.py [--scene renders/default.yaml] [--out /tmp/bench-loop]
                                      [--jobs N] [--no-serial]

The loop renders with ``--jobs`` processes (default: every core); the calibration session
is then rendered again in one process, timed, and compared byte for byte (serial vs
parallel rendering, the figure the README quotes).

The planner's targets per second are compared, in the same process, with a plain numpy
baseline: the base model's closed-form inverse kinematics alone (no effects, no checks).
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="renders/default.yaml")
    ap.add_argument("--out", default="/tmp/bench-loop")
    ap.add_argument("--jobs", type=int, default=None)
    ap.add_argument("--no-serial", action="store_true", help="skip the serial render")
    a = ap.parse_args()
    from vision_cal.dataset.calibration import load_calibration
    from vision_cal.model.kinematics import inverse
    from vision_cal.actions.loop import format_table, run_loop
    from vision_cal.plan.compensate import plan_targets

    t0 = time.perf_counter()
    doc, run = run_loop(a.scene, out_dir=a.out, jobs=a.jobs)
    total = time.perf_counter() - t0
    print(f"closed loop on {a.scene}: {total:.1f} s wall")
    for k, v in doc["stages_s"].items():
        print(f"  {k:<42}{v:8.2f} s  ({100 * v / total:4.1f} %)")
    print(format_table(doc).splitlines()[-2])
    print(format_table(doc).splitlines()[-1])
    if not a.no_serial:
        _serial_render(a, doc)
    model, _ = load_calibration(run.out_path)
    rng = np.random.default_rng(0)
    xy = np.column_stack([rng.uniform(-250, 100, 2000), rng.uniform(-200, 150, 2000)])
    ids = [str(i) for i in range(len(xy))]
    t = time.perf_counter()
    planned = plan_targets(model, ids, xy)
    tp = time.perf_counter() - t
    t = time.perf_counter()
    for _ in range(10):
        try:
            inverse(model.params, xy)
        except Exception:
            pass
    tb = (time.perf_counter() - t) / 10
    ok = sum(p.status == "ok" for p in planned)
    print(f"planner: {len(xy) / tp:.0f} targets/s with every effect compensated "
          f"({ok}/{len(xy)} planned); baseline vectorised numpy IK {len(xy) / tb:.0f} targets/s "
          f"-> planner costs {tp / tb:.0f}x the bare IK")


def _serial_render(a, doc) -> None:
    """The calibration session again in one process: time and bytes against the loop's."""
    import hashlib
    import os
    from pathlib import Path

    from vision_cal.world.dataset import render_dataset
    from vision_cal.world.scene import load_scene

    jobs = a.jobs or os.cpu_count() or 1
    t = time.perf_counter()
    from vision_cal.estimate.paper import pilot_params

    serial = render_dataset(load_scene(a.scene), Path(a.out) / "session_serial", jobs=1,
                            pilot=pilot_params)
    ts = time.perf_counter() - t
    tp = doc["stages_s"]["render calibration session"]

    def digest(folder):
        return {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
                for p in sorted(Path(folder).iterdir()) if p.is_file()}

    same = digest(serial) == digest(Path(a.out) / "session")
    print(f"render calibration session: {ts:.1f} s with 1 job, {tp:.1f} s with {jobs} jobs "
          f"({ts / tp:.2f}x); identical bytes: {same}")


if __name__ == "__main__":
    main()
