"""The README's "Calibrate your robot" page on a simulated robot: time per step, accuracy.

Usage: .venv/bin/python bench/walkthrough.py [--out /tmp/bench-walkthrough]

Runs tests/test_walkthrough.py (sheet, design pilot, draw, photograph, calibrate pilot,
design, draw, photograph, calibrate --report, plan --program spel, the program on the true
robot) and prints its walkthrough.json: seconds per step, the compensated targets' RMS and
max miss on the true robot (mm), and the RMS of plan.csv's predicted std_mm.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="/tmp/bench-walkthrough")
    a = ap.parse_args()
    root = Path(__file__).resolve().parents[1]
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                        str(root / "tests" / "test_walkthrough.py"), "--basetemp", a.out],
                       cwd=root, capture_output=True, text=True)
    found = sorted(Path(a.out).glob("walkthrough*/walkthrough.json"))
    if not found:
        print(r.stdout[-2000:], r.stderr[-2000:], sep="\n")
        sys.exit(1)
    doc = json.loads(found[-1].read_text())
    for k, v in doc["stages_s"].items():
        print(f"{k:<28}{v:8.1f} s")
    print(f"{'total':<28}{doc['total_s']:8.1f} s")
    print(f"compensated targets on the true robot: RMS {doc['rms_mm']:.4f} mm, max "
          f"{doc['max_mm']:.4f} mm over {doc['targets']} targets; predicted std (per axis, "
          f"RMS) {doc['predicted_std_mm_rms']:.4f} mm; effects found: "
          f"{', '.join(doc['effects']) or 'none'}")
    sys.exit(r.returncode)


if __name__ == "__main__":
    main()
