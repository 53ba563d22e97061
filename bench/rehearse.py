"""The README's "Rehearse it first" and `vision-cal verify` on new seeds: figures.

Usage: .venv/bin/python bench/rehearse.py [--seeds 101 102] [--out /tmp/bench-rehearse]

For each seed: the README block's commands (tests/test_rehearsal.py reads them) with the
simulated robot's seed replaced, then three checks drawn on fresh sheets placed elsewhere
(base +8/+6 mm, z1 +0.7 deg): the unchanged robot, joint 2's zero moved by +0.04 deg, L1
longer by 0.2 mm, each with `design --verify --iso9283 10`. Prints the calibration against
the truth (in reported std), the compensated targets' true and measured misses, each
check's verdict and z2 change (in its std), and ISO 9283 AP/RP per point.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.readme import type_line  # noqa: E402  (the README's lines, typed as the tests type them)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[101, 102])
    ap.add_argument("--out", default="/tmp/bench-rehearse")
    a = ap.parse_args()
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    from tests.test_rehearsal import readme_commands

    for seed in a.seeds:
        d = Path(a.out) / f"seed{seed}"
        shutil.rmtree(d, ignore_errors=True)
        d.mkdir(parents=True)
        for line in readme_commands():
            type_line(line, d)
            if line.endswith("-o true_robot.yaml"):
                sim = yaml.safe_load((d / "true_robot.yaml").read_text())
                sim["seed"] = seed
                (d / "true_robot.yaml").write_text(yaml.safe_dump(sim))
        cal = json.loads((d / "cal" / "calibration.json").read_text())
        truth = json.loads((d / "plan" / "truth.json").read_text())["params"]
        p, s = cal["params"], cal["std"]
        z = {k: (p[k] - truth[k]) / s[k] for k in ("L1_mm", "L2_mm")}
        for i, k in enumerate(("z1", "z2")):
            z[k] = (p["joint_zero_deg"][i] - truth["joint_zero_deg"][i]) / s["joint_zero_deg"][i]
        bl = [e for e in cal["effects"] if e["name"] == "joint_backlash"]
        print(f"seed {seed}: calibration - truth in std: "
              + ", ".join(f"{k} {v:+.2f}" for k, v in z.items())
              + (f"; backlash j2 {bl[0]['deg']:.4f} +- {bl[0]['std']:.4f} deg (truth 0.1)"
                 if bl else "; no backlash found"))
        hits = json.loads((d / "hits_cal" / "calibration.json").read_text())["targets"]
        tm = json.loads((d / "hits" / "truth.json").read_text())["marks"]
        true = np.array([np.hypot(*np.subtract(tm[r["id"]], r["target_mm"])) for r in hits])
        seen = np.array([r["error_norm_mm"] for r in hits])
        print(f"  targets: true miss RMS {np.sqrt(np.mean(true**2)):.4f} mm (max "
              f"{true.max():.4f}), measured RMS {np.sqrt(np.mean(seen**2)):.4f} mm")
        base = yaml.safe_load((d / "true_robot.yaml").read_text())
        for name, dz2, dl1 in (("unchanged", 0.0, 0.0), ("z2 +0.04 deg", 0.04, 0.0),
                               ("L1 +0.2 mm", 0.0, 0.2)):
            sim = json.loads(json.dumps(base))
            h = sim["hidden"]
            h["joint_zero_deg"] = [h["joint_zero_deg"][0] + 0.7, h["joint_zero_deg"][1] + dz2]
            h["base_mm"] = [h["base_mm"][0] + 8.0, h["base_mm"][1] + 6.0]
            h["L1_mm"] = h["L1_mm"] + dl1
            sim["seed"] = seed + 1000
            tag = name.split()[0]
            (d / f"{tag}.yaml").write_text(yaml.safe_dump(sim))
            for line in (f"vision-cal design robot.yaml --sheet sheet/sheet.json --verify "
                         f"cal/calibration.json --iso9283 10 --out {tag}/",
                         f"vision-cal simulate {tag}/ --truth {tag}.yaml --out {tag}/",
                         f"vision-cal verify cal/calibration.json {tag}/"):
                type_line(line, d)
            v = json.loads((d / f"{tag}_verify" / "verify.json").read_text())
            c = v["changes"]["z2_deg"]
            iso = v.get("iso9283") or {}
            print(f"  check, {name}: verdict '{v['verdict']}'; z2 change {c['delta']:+.4f} +- "
                  f"{c['std']:.4f} deg ({(c['delta'] - dz2) / c['std']:+.2f} std from the "
                  f"truth); L1 change {v['changes']['L1_mm']['delta']:+.4f} +- "
                  f"{v['changes']['L1_mm']['std']:.4f} mm; RMS {v['rms_mm']['sheet_placed']:.4f}"
                  " mm")
            if iso:
                print("    ISO 9283: " + ", ".join(
                    f"{k} AP {x['AP_mm']:.4f} RP {x['RP_mm']:.4f}" for k, x in iso.items())
                    + " mm")


if __name__ == "__main__":
    main()
