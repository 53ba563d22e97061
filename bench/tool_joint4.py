"""Issue #21 figures: the tool and joint 4, the plan with orientation, three placements.

Usage: .venv/bin/python bench/tool_joint4.py [--seeds 10] [--first 1000] [--sigma 0.01]
       [--render N] [--keep DIR] [--alone]

Seeds ``first .. first + seeds - 1`` (the tests use 2024, 77, 100, 5, 7, 11, 21: not these).
Marks come from the world's own truth model (world/truth_model.py) with isotropic noise
``sigma`` mm per axis, as ``measured_mm`` would carry them; ``--render N`` adds N cases
measured from a rendered photograph (:func:`render_case`, seeds ``first + 1 ..``).

1. tool_mm and joint-4 effects: SM5-like truth with a tool of random direction and 15-35 mm
   radius, joint-4 gear scale 0.004 and backlash 0.1 deg; 40 marks over the sheet's pose
   range with j4 uniform in +-170 deg; least squares with joint-4 scale and backlash.
   Prints |tool error| (mm), and each joint-4 effect's error in reported std.
2. The plan with orientation: 10 targets with random theta, planned with that calibration,
   driven on the true robot: position error (mm) and orientation error (deg).
3. Three placements of one sheet (joint-1 ranges centred at -90, 0, 90 deg, 40 marks each)
   with a hidden joint-1 once-per-turn error of 0.003 deg, random phase: how often the
   joint calibration names it (and its amplitude error in std), how often a placement
   alone does, with the same selection rule, and how often an effect that is not there is
   claimed (beside the true one, and on clean seeds ``+700`` with no error at all).
3b. ``--alone``: each placement of 3 (both approach directions) calibrated alone by the
   single-folder run: the effects it names, its verdict and expected target error, and the
   largest error on the true robot over its own joint-1 range and the others'.
4. Rendered (``--render``): a 1600 x 1200 photo of 48 marks (30 + 6 informative turned
   over six joint-4 angles, four joint-4 circles of the design) of a robot with a tool
   (15-35 mm, the robot file's guess 2 mm off), a joint-4 gear error 0.003 and a joint-2
   backlash 0.05 deg, calibrated by the pipeline (the diagnosis with the tool): tool error,
   each hidden effect in std, effects claimed that are not there, a plan with orientation
   on the true robot.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.tool.oracle import tool_angle_deg
from vision_cal.estimate.placements import Placement, fit_placements
from vision_cal.model.tool_fit import fit_tool
from vision_cal.estimate.verdict import judge
from vision_cal.model.robot import JointBacklash, JointScale
from vision_cal.actions.pipeline import calibrate_dataset
from vision_cal.plan.orient import plan_poses
from vision_cal.world.truth_model import TrueRobot

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
    ang = (tool_angle_deg(truth, qp, sp) - theta[ok] + 180) % 360 - 180
    return float(np.hypot(*(f.tool_mm - tool))), float(z_scale), float(z_band), pos, ang


def _placement_truths(rng, amp_deg: float) -> list:
    """(k, joint-1 centre, z1, base, the true robot in that sheet's frame) per placement of
    :data:`PLACES`, with a once-per-turn joint-1 error of ``amp_deg`` (phase: rng's draw)."""
    cyc = {"name": "joint_cyclic", "joint": 1, "harmonic": 1, "deg": amp_deg,
           "phase_deg": float(rng.uniform(-180, 180))}
    return [(k, c, a, b, TrueRobot.from_json({**SM5, "joint_zero_deg": [a, -8.13],
                                              "base_mm": list(b)}, [cyc]))
            for k, (c, a, b) in enumerate(PLACES)]


def placements_case(seed: int, sigma: float, amp_deg: float = 0.003):
    rng = np.random.default_rng(seed)
    places = []
    for k, c, a, b, truth in _placement_truths(rng, amp_deg):
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


def alone_case(seed: int, sigma: float, amp_deg: float = 0.003) -> list[dict]:
    """Each of :func:`placements_case`'s three placements (both approach directions here, so
    the plan identifies backlash) calibrated alone by the user's single-folder run
    (``calibrate_dataset``, 8 of 40 marks held out; the marks' ``sigma_mm`` set to the
    noise, as a measurement states it): the effects it names, its verdict, and the largest
    error on the true robot over each placement's joint-1 range (its own and the two it
    never saw)."""
    rng = np.random.default_rng(seed)
    out = []
    for k, c, a, b, truth in _placement_truths(rng, amp_deg):
        q = np.column_stack([rng.uniform(c - 67, c + 67, 40), rng.uniform(-120, -30, 40)])
        ap = np.where(rng.random((40, 2)) < 0.5, -1.0, 1.0)
        xy = truth.pen_mm(q, ap) + rng.normal(0, sigma, (40, 2))
        nominal = {"L1_mm": 350.0, "L2_mm": 260.0, "joint_zero_deg": [a + 2, 0.0],
                   "base_mm": [b[0] + 20, b[1] - 10], "home_deg": [float(c), -60.0]}
        marks = [{"id": f"m{i:02d}", "joints_deg": qi.tolist(), "approach": si.tolist(),
                  "measured_mm": p.tolist(), **({"role": "validation"} if i % 5 == 4 else {})}
                 for i, (qi, p, si) in enumerate(zip(q, xy, ap))]
        with tempfile.TemporaryDirectory() as tmp:
            d = Path(tmp)
            (d / "session.json").write_text(json.dumps({"format": "vision-cal/1",
                                                        "robot": nominal, "marks": marks}))
            run = calibrate_dataset(d, out_dir=d / "out")
        doc = run.document
        for m in doc["marks"].values():
            m["sigma_mm"] = sigma
        v = judge(doc, repeatability_mm=0.0)
        g = np.random.default_rng(1)
        worst = []
        for cc, _, _ in PLACES:
            qq = np.column_stack([g.uniform(cc - 67, cc + 67, 400), g.uniform(-120, -30, 400)])
            worst.append(float(np.hypot(*(run.model.predict(qq, np.ones((400, 2)))
                                          - truth.pen_mm(qq)).T).max()))
        out.append({"placement": k, "effects": [e["name"] + (f"({e['joint']})" if "joint" in e
                                                             else "") for e in doc["effects"]],
                    "status": v.status, "expected_mm": v.expected_target_error_mm,
                    "own_mm": worst[k], "other_mm": max(w for i, w in enumerate(worst) if i != k)})
    return out


def render_case(seed: int, *, width_px: int = 1600, keep: Path | None = None) -> dict:
    """One rendered dataset (one photo, ``width_px`` wide, 30 + 6 informative marks turned
    over six joint-4 angles plus the design's four joint-4 circles: 48 marks) of a true
    robot with a tool, a joint-4 gear error and a joint-2 backlash; calibrated from the
    photo (the dataset and its calibration kept in ``keep``/seed when given). Returns the
    tool error, each hidden effect's error in its reported std, the
    effects claimed that are not there, and a plan with orientation (10 targets) driven
    on the true robot."""
    import copy

    import yaml

    from vision_cal.estimate.paper import pilot_params
    from vision_cal.design.joint4 import circle_triples, turn_joint4
    from vision_cal.model.kinematics import forward
    from vision_cal.world import dataset as ds
    from vision_cal.world.scene import scene_from_dict
    from vision_cal.world.sheet import make_sheet

    rng = np.random.default_rng(seed)
    r, ang = rng.uniform(15, 35), rng.uniform(-np.pi, np.pi)
    tool = [float(r * np.cos(ang)), float(r * np.sin(ang))]
    nominal_tool = [round(tool[0] + rng.uniform(-2, 2), 1), round(tool[1] + rng.uniform(-2, 2), 1)]
    hidden = {("joint_scale", 4): 0.003, ("joint_backlash", 2): 0.05}
    d = copy.deepcopy(yaml.safe_load((ROOT / "renders" / "small.yaml").read_text()))
    d["seed"] = seed
    d["camera"].update(size_px=[width_px, width_px * 3 // 4], f_px=1734.0 * width_px / 1600,
                       n_views=1, moving=False)
    d["photos"] = {"mode": "single", "texture_px_per_mm": 6.0}
    d["plan"].update(n_calibration=30, n_validation=6)
    d["robot"].update(effects=[{"name": "joint_scale", "joint": 4, "scale": 0.003},
                               {"name": "joint_backlash", "joint": 2, "deg": 0.05}],
                      tool_mm=tool, controller="kinematic")
    d["robot"]["nominal"]["tool_mm"] = nominal_tool
    sc = scene_from_dict(d, file="bench")
    s = sc.sheet
    sheet = make_sheet(size_mm=s.size_mm, bottom_left_mm=s.bottom_left_mm,
                       dictionary=s.dictionary, marker_mm=s.marker_mm, grid=s.grid,
                       margin_mm=s.margin_mm)
    plan = ds.build_plan(sc, sheet, pilot=pilot_params, rng=seed)
    pilot = pilot_params(*ds.pilot_marks(sc, rng=seed))
    points = forward(pilot, [m.joints_deg for m in plan])
    plan, j4 = turn_joint4(plan, pilot, nominal_tool)
    tri, t4 = circle_triples(pilot, nominal_tool, sheet, avoid_xy=points, rng=seed,
                             clearance_mm=sc.robot.pen_diameter_mm / 2 + 3.0 + 3.0)
    plan, j4 = list(plan) + tri, {**j4, **t4}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp) if keep is None else Path(keep) / str(seed)
        folder = ds.render_dataset(sc, Path(tmp) / "data", plan=plan, joint4_deg=j4)
        run = calibrate_dataset(folder, out_dir=Path(tmp) / "out")
        truth_doc = json.loads((folder / "truth.json").read_text())
    doc = run.document
    err = np.subtract(doc["params"]["tool_mm"], tool)
    std = np.array(doc["std"]["tool_mm"])
    z, extra = {}, []
    for e in doc["effects"]:
        key = (e["name"], e.get("joint"))
        if key in hidden:
            z[key] = (e.get("scale", e.get("deg")) - hidden[key]) / e["std"]
        elif e["name"] != "unexplained":
            extra.append(f"{e['name']}(joint {e.get('joint')})")
    truth = TrueRobot.from_json(truth_doc["params"], truth_doc["effects"])
    targets = np.column_stack([rng.uniform(-200, 200, 10), rng.uniform(-130, 130, 10)])
    theta = rng.uniform(-180, 180, 10)
    plan_t = plan_poses(run.model, [f"t{i}" for i in range(10)], targets, theta)
    ok = [i for i, p in enumerate(plan_t) if p.target.status == "ok"]
    qp = np.array([[*plan_t[i].target.q_deg, plan_t[i].q4_deg] for i in ok])
    sp = np.ones((len(ok), 3))
    pos = np.hypot(*(truth.pen_mm(qp, sp) - targets[ok]).T)
    angle = (tool_angle_deg(truth, qp, sp) - theta[ok] + 180) % 360 - 180
    return {"seed": seed, "tool_err_mm": float(np.hypot(*err)), "tool_z": np.abs(err / std),
            "z": z, "missing": [k for k in hidden if k not in z], "extra": extra,
            "pos_mm": pos, "angle_deg": angle, "n_marks": len(plan),
            "n_measured": len(doc["marks"]), "outliers": len(doc.get("outliers", [])),
            "unexplained": any(e["name"] == "unexplained" for e in doc["effects"]),
            "verdict": doc.get("verdict", {}).get("status"),
            "reasons": doc.get("verdict", {}).get("reasons", [])}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=10, help="0: the rendered cases only")
    ap.add_argument("--first", type=int, default=1000)
    ap.add_argument("--sigma", type=float, default=0.01)
    ap.add_argument("--render", type=int, default=0, metavar="N",
                    help="also N rendered cases (seeds first+1 ..)")
    ap.add_argument("--keep", type=Path, help="keep the rendered datasets here (KEEP/seed)")
    ap.add_argument("--alone", action="store_true",
                    help="3b only: each placement calibrated alone by the single-folder run")
    a = ap.parse_args()
    if a.alone:
        print(f"3b. one placement alone (single-folder run), joint-1 once-per-turn 0.003 deg "
              f"(seeds {a.first + 500}-{a.first + 499 + a.seeds}): verdict, expected target "
              "error, largest error on the true robot over its own and the other joint-1 ranges")
        for s in range(a.first + 500, a.first + 500 + a.seeds):
            for c in alone_case(s, a.sigma):
                print(f"   seed {s} placement {c['placement']}: {', '.join(c['effects']) or 'none'};"
                      f" {c['status']}, expected {c['expected_mm']:.4f} mm; on the true robot "
                      f"own range {c['own_mm']:.4f} mm, other ranges {c['other_mm']:.4f} mm",
                      flush=True)
        return
    if a.render:
        for k in range(a.render):
            c = render_case(a.first + 1 + k, keep=a.keep)
            print(f"4. rendered photo (seed {c['seed']}, {c['n_marks']} marks, {c['n_measured']} "
                  f"measured, {c['outliers']} left out as outliers): |tool error| "
                  f"{c['tool_err_mm']:.4f} mm ({np.round(c['tool_z'], 2).tolist()} std); "
                  + ", ".join(f"{n}(joint {j}) {v:+.2f} std" for (n, j), v in c["z"].items())
                  + (f"; MISSED {c['missing']}" if c["missing"] else "")
                  + f"; claimed but not there: {', '.join(c['extra']) or 'none'}"
                  + ("; unexplained reported" if c["unexplained"] else "")
                  + f"; plan with orientation on the true robot: position max "
                  f"{c['pos_mm'].max():.4f} mm, orientation max "
                  f"{np.abs(c['angle_deg']).max():.4f} deg"
                  + f"; verdict {c['verdict']}"
                  + "".join(f"\n     - {r}" for r in c["reasons"]), flush=True)
        if not a.seeds:
            return
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
    hits, alone_hits, zz, false, clean_false = 0, 0, [], 0, 0
    for s in seeds:
        found, z, alone, names = placements_case(s + 500, a.sigma)
        hits += found
        alone_hits += sum(alone)
        zz.append(z)
        extra = [n for n in names if n != "joint_cyclic(joint 1, harmonic 1)"]
        false += bool(extra)
        _, _, _, clean = placements_case(s + 700, a.sigma, amp_deg=0.0)
        clean_false += bool(clean)
        print(f"   seed {s + 500}: joint {'found' if found else 'MISSED'} ({', '.join(names) or 'none'}), "
              f"alone {sum(alone)} of 3; clean seed {s + 700}: {', '.join(clean) or 'nothing'} "
              "claimed")
    print(f"   joint calibration names it in {hits} of {a.seeds}; amplitude |error| / std max "
          f"{np.nanmax(np.abs(zz)):.2f}; one placement alone names it in {alone_hits} of "
          f"{3 * a.seeds}; an effect not there claimed in {false} of {a.seeds} (with the "
          f"error) and {clean_false} of {a.seeds} (clean)")

if __name__ == "__main__":
    main()
