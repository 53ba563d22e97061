"""Sheets that are not flat (issue 13): calibration figures on rendered dataset folders.

For each folder (rendered with truth.json): calibrate it, then print the mark error
against the ink (RMS), the effects found against the true ones (backlash error in %),
whether sheet_height / sheet_affine / unexplained were claimed, and the compensated
plan's miss: the calibrated model plans a grid of targets over the sheet, the true robot
(truth.json params and robot effects, kinematic) goes there; RMS of where it lands minus
the target (mm). Baseline in the same run: the nominal model's plan.

Usage::

    .venv/bin/python bench/sheet_height.py DIR [DIR ...]

(render the folders first, e.g. ``vision-cal render renders/bumped_tilted.yaml --out DIR
--seed 31``, or let ``bench/measure.py --reference`` render them).
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

ROBOT_EFFECTS = ("joint_backlash", "joint_scale", "joint_cyclic", "sheet_affine")


def plan_miss_mm(model, truth_model, extent_mm) -> float:
    from vision_cal.plan.compensate import plan_targets

    x0, y0, x1, y1 = extent_mm
    xs, ys = np.meshgrid(np.linspace(x0 + 30, x1 - 30, 12), np.linspace(y0 + 30, y1 - 30, 9))
    tg = np.column_stack([xs.ravel(), ys.ravel()])
    out = []
    for appr in ((1, 1), (-1, -1), (1, -1)):
        planned = plan_targets(model, [str(i) for i in range(len(tg))], tg, approach=appr)
        ok = [p for p in planned if p.status == "ok"]
        q = np.array([p.q_deg for p in ok])
        s = np.array([p.approach for p in ok], float)
        got = truth_model.predict(q, s)
        out.append(got - np.array([p.target_mm for p in ok]))
    e = np.concatenate(out)
    return float(np.sqrt(np.mean(np.sum(e**2, axis=1))))


def main() -> int:
    from vision_cal.dataset.calibration import load_calibration
    from vision_cal.kinematics import ScaraParams
    from vision_cal.model import RobotModel, effect_from_json
    from vision_cal.pipeline import calibrate_dataset

    print(f"{'dataset':34s} {'marks um':>8s} {'backlash %':>10s} {'claimed':30s} "
          f"{'plan um':>7s} {'nominal plan um':>15s}")
    for folder in map(Path, sys.argv[1:]):
        t = json.loads((folder / "truth.json").read_text())
        tmodel = RobotModel(ScaraParams.from_json(t["params"]),
                            tuple(effect_from_json(e) for e in t["effects"]
                                  if e["name"] in ROBOT_EFFECTS))
        out = Path(tempfile.mkdtemp(prefix="bench-sheet-height-"))
        run = calibrate_dataset(folder, out_dir=out, truth=True, jobs=2)
        doc = run.document
        model, _ = load_calibration(run.out_path)
        nominal, _ = load_calibration(run.out_path, which="nominal")
        found = [e for e in doc["effects"]]
        tb = {e["joint"]: e["deg"] for e in t["effects"] if e["name"] == "joint_backlash"}
        fb = {e["joint"]: e["deg"] for e in found if e["name"] == "joint_backlash"}
        bl = ", ".join(f"j{j} {100 * (fb.get(j, 0.0) / d - 1):+.1f}" for j, d in tb.items())
        names = sorted({e["name"] for e in found} - {"joint_backlash"})
        extra = [f"joint_backlash j{j}" for j in fb if j not in tb]
        ext = tuple(t.get("sheet_height", {}).get("grid", {}) and (
            min(t["sheet_height"]["grid"]["x_mm"]), min(t["sheet_height"]["grid"]["y_mm"]),
            max(t["sheet_height"]["grid"]["x_mm"]), max(t["sheet_height"]["grid"]["y_mm"]))
            or (-297.0, -210.0, 297.0, 210.0))
        print(f"{folder.name:34s} {1000 * doc['truth_comparison'].get('mark_rms_mm', np.nan):8.1f}"
              f" {bl:>10s} {','.join(names + extra) or '-':30s} "
              f"{1000 * plan_miss_mm(model, tmodel, ext):7.1f} "
              f"{1000 * plan_miss_mm(nominal, tmodel, ext):15.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
