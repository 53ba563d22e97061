"""Resource limits, measured: peak memory and time of bad and large inputs.

Each case runs in a fresh Python process (so its peak RSS, ``resource.getrusage``
``ru_maxrss``, is its own; workers' peak from ``RUSAGE_CHILDREN``) and prints:

- ``baseline``: one good 1000x750 photo measured (the floor every run pays: imports,
  OpenCV, one photo);
- ``bomb30k``: that photo plus a 1 MB PNG of 30000x30000 px, ``bomb12k`` (144 MP, under
  Pillow's own error limit), ``claims100k`` (a header claiming 100000x100000 over a few
  bytes): all three in one folder, measured with jobs=2; each is refused from its header;
- ``decode12k``: what plain ``cv2.imdecode`` of the 144 MP PNG costs in the same setting
  (the baseline the limit saves; the 900 MP one, ~2.7 GB decoded, is not run on a shared
  machine);
- ``photos100``: a 100-photo folder of the finished sheet (1000x750, synthetic), jobs=2,
  cold cache, then warm cache.

Usage::

    .venv/bin/python bench/limits.py [--photos 100] [--folder DIR]
"""

from __future__ import annotations

import argparse
import json
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _peak_mib(who) -> float:
    return resource.getrusage(who).ru_maxrss / 1024.0  # Linux: KiB


def _world(n_marks=6):
    from tests.measure import synth_measure as sm

    sheet = sm.small_sheet()
    targets = sm.free_targets(sheet, n_marks, rng=21, box=(85.0, 62.0))
    q = sm.plan_for(targets)
    return sm, sheet, targets, q


def _session(folder, files, sm, sheet, q):
    ids = [f"c{i}" for i in range(len(q))]
    sm.write_session(folder, sm.session_json(sheet, marks=list(zip(ids, q)),
                                             images=[(f, ids) for f in files],
                                             robot=sm.NOMINAL))


def prepare(folder: Path, n_photos: int) -> None:
    from tests.measure.test_photo_files import bomb_png

    sm, sheet, targets, q = _world()
    tex = sm.texture(sheet, targets, rng=1)
    K, T = sm.view(tilt_deg=10.0, azimuth_deg=60.0)
    good = sm.photo(sheet, tex, K=K, T=T, rng=2)
    for name in ("baseline", "bombs", "photos100"):
        (folder / name).mkdir(parents=True, exist_ok=True)
    sm.write_png(folder / "baseline" / "a.png", good)
    _session(folder / "baseline", ["a.png"], sm, sheet, q)
    sm.write_png(folder / "bombs" / "a.png", good)
    bombs = {"bomb30k.png": bomb_png(30000, 30000), "bomb12k.png": bomb_png(12000, 12000),
             "claims100k.png": bomb_png(100000, 100000, full=False)}
    for name, data in bombs.items():
        (folder / "bombs" / name).write_bytes(data)
    _session(folder / "bombs", ["a.png", *bombs], sm, sheet, q)
    p100 = folder / "photos100"
    files = []
    for k in range(n_photos):
        K, T = sm.view(tilt_deg=6.0 + (k % 9), azimuth_deg=37.0 * k)
        f = f"img_{k:03d}.png"
        sm.write_png(p100 / f, sm.photo(sheet, tex, K=K, T=T, rng=100 + k))
        files.append(f)
    _session(p100, files, sm, sheet, q)


def run_case(case: str, folder: Path) -> dict:
    """In this (fresh) process: run one case, return its figures."""
    import numpy as np

    from vision_cal.dataset.session import load_session
    from vision_cal.actions.measure_folder import measure_folder

    out = Path(tempfile.mkdtemp(prefix="vision-cal-limits-"))
    try:
        t0 = time.perf_counter()
        if case == "decode12k":
            import cv2

            data = (folder / "bombs" / "bomb12k.png").read_bytes()
            img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
            res = {"decoded_px": list(img.shape[:2])}
            del img
        else:
            src = {"baseline": "baseline", "bombs": "bombs", "photos100": "photos100"}[case]
            m = measure_folder(load_session(folder / src), out_dir=out, jobs=2)
            res = {"images": {im.file: im.status if im.status == "ok" else im.reason
                              for im in m.images} if case != "photos100" else
                   sum(im.status == "ok" for im in m.images), "marks": len(m.marks)}
            if case == "photos100":
                t1 = time.perf_counter()
                res["cold_s"] = t1 - t0
                measure_folder(load_session(folder / src), out_dir=out, jobs=2)
                res["warm_s"] = time.perf_counter() - t1
        res["time_s"] = time.perf_counter() - t0
    finally:
        shutil.rmtree(out, ignore_errors=True)
    res["peak_rss_mib"] = _peak_mib(resource.RUSAGE_SELF)
    res["peak_worker_rss_mib"] = _peak_mib(resource.RUSAGE_CHILDREN)
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photos", type=int, default=100)
    ap.add_argument("--folder", default=None, help="where the inputs go (default: temporary)")
    ap.add_argument("--case", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.case:
        print(json.dumps(run_case(args.case, Path(args.folder))))
        return
    folder = Path(args.folder or tempfile.mkdtemp(prefix="vision-cal-limits-in-"))
    t0 = time.perf_counter()
    prepare(folder, args.photos)
    print(f"inputs in {folder} ({time.perf_counter() - t0:.1f} s to make); "
          f"bomb30k.png is {(folder / 'bombs' / 'bomb30k.png').stat().st_size / 1e6:.2f} MB")
    rows = {}
    for case in ("baseline", "bombs", "decode12k", "photos100"):
        r = subprocess.run([sys.executable, __file__, "--case", case, "--folder", str(folder)],
                           capture_output=True, text=True, check=True)
        rows[case] = json.loads(r.stdout.strip().splitlines()[-1])
    b, bo, d, p = (rows[k] for k in ("baseline", "bombs", "decode12k", "photos100"))
    print(f"{'case':<12} {'time s':>8} {'peak RSS MiB':>13} {'worker peak MiB':>16}")
    for k, r in rows.items():
        print(f"{k:<12} {r['time_s']:8.2f} {r['peak_rss_mib']:13.0f} "
              f"{r['peak_worker_rss_mib']:16.0f}")
    print("bombs: " + "; ".join(f"{f}: {v}" for f, v in bo["images"].items()))
    print(f"bombs cost over the baseline: {bo['time_s'] - b['time_s']:+.2f} s, peak RSS "
          f"{bo['peak_rss_mib'] - b['peak_rss_mib']:+.0f} MiB (plain cv2.imdecode of the "
          f"144 MP one alone: {d['peak_rss_mib'] - b['peak_rss_mib']:+.0f} MiB over the "
          f"baseline process, {d['time_s']:.2f} s)")
    print(f"{args.photos} photos, jobs=2: cold {p['cold_s']:.1f} s "
          f"({args.photos / p['cold_s']:.1f} photos/s), warm cache {p['warm_s']:.1f} s; "
          f"{p['images']} ok, {p['marks']} marks; peak RSS {p['peak_rss_mib']:.0f} MiB, "
          f"worker {p['peak_worker_rss_mib']:.0f} MiB")
    if not args.folder:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
