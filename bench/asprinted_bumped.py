"""The sheet as printed on paper that is not flat (issue 28): does the as-printed stage
take the parallax between camera places for print?

For each rendered folder (with truth.json; e.g. ``vision-cal render
renders/bumped_moving.yaml --out DIR --seed N``): measure it three ways, the as-printed
stage off (``min_places`` huge), on with in-plane shifts only (``release_heights`` off:
the stage as first merged), and on with each corner's height released (the default), and
print the marks' error against truth.json (RMS um), the ``print`` block's deviation
(``rms_mm``, whether it was applied), what the views leave unresolved, and the heights'
RMS the solve found.

Usage::

    .venv/bin/python bench/asprinted_bumped.py DIR [DIR ...]
"""

from __future__ import annotations

import json
import shutil
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(folders: list[str]) -> int:
    if not folders or {"-h", "--help"} & set(folders):   # the usage, not a run of minutes
        print(__doc__)
        return 0
    from vision_cal.config import DEFAULT
    from vision_cal.dataset.session import load_session
    from vision_cal.actions.measure_folder import measure_folder

    ways = {"off": replace(DEFAULT, as_printed=replace(DEFAULT.as_printed, min_places=10**6)),
            "in-plane only": replace(DEFAULT, as_printed=replace(DEFAULT.as_printed,
                                                                 release_heights=False)),
            "with heights": DEFAULT}
    print(f"{'folder':24s} {'as printed':14s} {'marks um':>8s} {'print rms':>9s} "
          f"{'applied':>7s} {'unresolved':>10s} {'height rms':>10s}")
    for f in folders:
        folder = Path(f)
        tm = json.loads((folder / "truth.json").read_text())["marks"]
        tmp = Path(tempfile.mkdtemp(prefix="bench-ap-"))
        try:
            for name, cfg in ways.items():
                s = load_session(folder)
                meas = measure_folder(s, out_dir=tmp / name.replace(" ", "-"), jobs=1,
                                      cache_dir=tmp / "cache", config=cfg)
                keys = [k for k in meas.marks if k in tm and meas.marks[k].status == "ok"]
                e = np.array([meas.marks[k].xy_mm - np.asarray(tm[k]) for k in keys])
                rms = float(np.sqrt(np.mean(np.sum(e**2, axis=1))))
                pr = meas.print_summary or {}
                hr = pr.get("height_rms_mm")
                print(f"{folder.name:24s} {name:14s} {1000 * rms:8.1f} "
                      f"{pr.get('rms_mm', float('nan')):9.4f} {str(pr.get('applied', '-')):>7s} "
                      f"{pr.get('unresolved_mm', float('nan')):10.4f} "
                      f"{'-' if hr is None else f'{hr:.4f}':>10s}", flush=True)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
