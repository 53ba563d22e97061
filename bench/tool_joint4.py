"""Issue #21 figures: the tool and joint 4, the plan with orientation, three placements.

Usage: .venv/bin/python bench/tool_joint4.py [--seeds 10] [--first 1000] [--sigma 0.01]

Seeds ``first .. first + seeds - 1`` (the tests use 2024, 77, 100, 5, 7, 11: not these).
Marks come from the world's own truth model (render/truth_model.py) with isotropic noise
``sigma`` mm per axis, as ``measured_mm`` would carry them; ``--render`` adds one case
measured from a rendered photograph (1600 px wide, 30 + 6 marks at six joint-4 angles).

1. tool_mm and joint-4 effects: SM5-like truth with a tool of random direction and 15-35 mm
   radius, joint-4 gear scale 0.004 and backlash 0.1 deg; 40 marks over the sheet's pose
   range with j4 uniform in +-170 deg; least squares with joint-4 scale and backlash.
   Prints |tool error| (mm), and each joint-4 effect's error in reported std.
2. The plan with orientation: 10 targets with random theta, planned with that calibration,
   driven on the true robot: position error (mm) and orientation error (deg).
3. Three placements of one sheet (joint-1 ranges centred at -90, 0, 90 deg, 40 marks each)
   with a hidden joint-1 once-per-turn error of 0.003 deg, random phase: how often the
   joint calibration names it (and its amplitude error in std), and how often a placement
   alone does, with the same selection rule.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from vision_cal.calibrate.placements import Placement, fit_placements
from vision_cal.calibrate.tool import fit_tool
from vision_cal.model import JointBacklash, JointScale
from vision_cal.plan.orient import plan_poses
from vision_cal.render.truth_model import TrueRobot

SM5 = {"L1_mm": 344.05, "L2_mm": 259.87, "joint_zero_deg": [-2.57, -8.13],
       "base_mm": [-424.26, -230.35]}
PLACES = [(-90, -95.0, (-50.0, 420.0)), (0, -3.0, (-420.0, -230.0)), (90, 85.0, (300.0, -400.0))]


def tool_case(seed: int, sigma: float):
    rng = np.random.default_rng(seed)
    r, a = rng.uniform(15, 35), rng.uniform(-np.pi, np.pi)
    tool = np.array([r * np.cos(a), r * np.sin(a)])
    truth = TrueRobot.from_json({**SM5, "tool_mm": tool.tolist()},
                                [{"name": "joint_scale", "joint": 4, "scale": 0.004},
                                 {"name": "joint_backlash", "joint": 4, "deg": 0.1}])
    n = 40
    q = np.column_stack([rng.uniform(0, 110, n), rng.uniform(-120, -30, n),
                         rng.uniform(-170, 170, n)])
    s = np.ones((n, 3))
    s[:, 2] = np.where(rng.random(n) < 0.5, -1.0, 1.0)
    xy = truth.pen_mm(q, s) + rng.normal(0.0, sigma, (n, 2))
    f = fit_tool(q[:, :2], q[:, 2], xy, approach=s,
                 effects=(JointScale(joint=4), JointBacklash(joint=4)))
    scale, band = f.joint4_effects
    z_scale = (scale.scale - 0.004) / f.effect_std(scale)[0]
    z_band = np.radians(band.deg - 0.1) / f.effect_std(band)[0]
    targets = np.column_stack([rng.uniform(-250, -50, 10), rng.uniform(-50, 150, 10)])
    theta = rng.uniform(-180, 180, 10)
    plan = plan_poses(f.fit.model, [f"t{i}" for i in range(10)], targets, theta)
    ok = [i for i, p in enumerate(plan) if p.target.status == "ok"]
    qp = np.array([[*plan[i].target.q_deg, plan[i].q4_deg] for i in ok])
    sp = np.ones((len(ok), 3))
    pos = np.hypot(*(truth.pen_mm(qp, sp) - targets[ok]).T)
    ang = (truth.tool_angle_deg(qp, sp) - theta[ok] + 180) % 360 - 180
    return float(np.hypot(*(f.tool_mm - tool))), float(z_scale), float(z_band), pos, ang


def placements_case(seed: int, sigma: float, amp_deg: float = 0.003):
    rng = np.random.default_rng(seed)
    cyc = {"name": "joint_cyclic", "joint": 1, "harmonic": 1, "deg": amp_deg,
           "phase_deg": float(rng.uniform(-180, 180))}
    places = []
    for k, (c, a, b) in enumerate(PLACES):
        truth = TrueRobot.from_json({**SM5, "joint_zero_deg": [a, -8.13], "base_mm": list(b)},
                                    [cyc])
        q = np.column_stack([rng.uniform(c - 67, c + 67, 40), rng.uniform(-120, -30, 40)])
        places.append(Placement(f"p{k}", q, truth.pen_mm(q) + rng.normal(0, sigma, (40, 2)),
                                np.ones((40, 2))))
    name = "joint_cyclic(joint 1, harmonic 1)"
    fit, _ = fit_placements(places)
    found = [k for k, e in enumerate(fit.effects) if e.label == name]
    z = (fit.effects[found[0]].deg - amp_deg) / np.degrees(
        np.hypot(*fit.effect_std(found[0])) / np.sqrt(2)) if found else np.nan
    alone = [any(e.label == name for e in fit_placements([p])[0].effects) for p in places]
    return bool(found), float(z), alone, [e.label for e in fit.effects]


def render_case(seed: int) -> None:
    """tool_mm and joint-4 scale from one rendered photo (1600 x 1200, 30 + 6 marks)."""
    import copy
    import tempfile

    import yaml

    from vision_cal.calibrate.paper import pilot_params
    from vision_cal.design.joint4 import turn_joint4
    from vision_cal.pipeline import calibrate_dataset
    from vision_cal.render import dataset as ds
    from vision_cal.render.scene import scene_from_dict
    from vision_cal.render.sheet import make_sheet

    tool, scale4 = [-17.0, 19.0], 0.003
    d = copy.deepcopy(yaml.safe_load((ROOT / "renders" / "small.yaml").read_text()))
    d["seed"] = seed
    d["camera"].update(size_px=[1600, 1200], f_px=1734.0, n_views=1, moving=False)
    d["photos"] = {"mode": "single", "texture_px_per_mm": 6.0}
    d["plan"].update(n_calibration=30, n_validation=6)
    d["robot"].update(effects=[{"name": "joint_scale", "joint": 4, "scale": scale4}],
                      tool_mm=tool, controller="kinematic")
    d["robot"]["nominal"]["tool_mm"] = [-15.0, 20.0]
    sc = scene_from_dict(d, file="bench")
    s = sc.sheet
    sheet = make_sheet(size_mm=s.size_mm, bottom_left_mm=s.bottom_left_mm,
                       dictionary=s.dictionary, marker_mm=s.marker_mm, grid=s.grid,
                       margin_mm=s.margin_mm)
    plan = ds.build_plan(sc, sheet, pilot=pilot_params, rng=seed)
    plan, j4 = turn_joint4(plan, pilot_params(*ds.pilot_marks(sc, rng=seed)), (-15.0, 20.0))
    with tempfile.TemporaryDirectory() as tmp:
        folder = ds.render_dataset(sc, Path(tmp) / "data", plan=plan, joint4_deg=j4)
        doc = calibrate_dataset(folder, out_dir=Path(tmp) / "out").document
    err = np.subtract(doc["params"]["tool_mm"], tool)
    std = np.array(doc["std"]["tool_mm"])
    print(f"4. rendered photo (seed {seed}): tool error {np.round(err, 4).tolist()} mm "
          f"(|error| {np.hypot(*err):.4f} mm, {np.round(np.abs(err) / std, 2).tolist()} std); "
          + "; ".join(f"{e['name']}(joint {e['joint']}) {e.get('scale', e.get('deg')):.5f} "
                      f"+- {e['std']:.5f}" for e in doc["effects"])
          + f" (true joint_scale(4) {scale4})")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--first", type=int, default=1000)
    ap.add_argument("--sigma", type=float, default=0.01)
    ap.add_argument("--render", action="store_true", help="also one rendered case")
    a = ap.parse_args()
    if a.render:
        render_case(a.first + 1)
    seeds = range(a.first, a.first + a.seeds)
    print(f"1-2. tool_mm, joint-4 effects, plan with orientation ({a.seeds} seeds, sigma "
          f"{a.sigma} mm)")
    errs, zs, zb, pos, ang = [], [], [], [], []
    for s in seeds:
        e, z1, z2, p, g = tool_case(s, a.sigma)
        errs.append(e)
        zs.append(z1)
        zb.append(z2)
        pos += list(p)
        ang += list(g)
    print(f"   |tool error| mm: max {max(errs):.4f}, mean {np.mean(errs):.4f}")
    print(f"   joint_scale(4) error / std: max |z| {np.max(np.abs(zs)):.2f}; "
          f"joint_backlash(4): max |z| {np.max(np.abs(zb)):.2f}")
    print(f"   plan on the true robot ({len(pos)} targets): position max {max(pos):.4f} mm, "
          f"orientation max {np.max(np.abs(ang)):.4f} deg")
    print(f"3. three placements, joint-1 once-per-turn 0.003 deg ({a.seeds} seeds)")
    hits, alone_hits, zz = 0, 0, []
    for s in seeds:
        found, z, alone, names = placements_case(s + 500, a.sigma)
        hits += found
        alone_hits += sum(alone)
        zz.append(z)
        print(f"   seed {s + 500}: joint {'found' if found else 'MISSED'} ({', '.join(names) or 'none'}), "
              f"alone {sum(alone)} of 3")
    print(f"   joint calibration names it in {hits} of {a.seeds}; amplitude |error| / std max "
          f"{np.nanmax(np.abs(zz)):.2f}; one placement alone names it in {alone_hits} of "
          f"{3 * a.seeds}")


if __name__ == "__main__":
    main()
