"""Coverage of the stated uncertainty (issue 37): does a planned target land inside the bound
vision-cal states for it, at the stated rate, on worlds it was not tuned on?

Usage: .venv/bin/python bench/coverage.py [--seeds 20] [--first-seed 5000]
       .venv/bin/python bench/coverage.py --render [--seeds 3] [--scenes clean,printed_off_six]
       .venv/bin/python bench/coverage.py --halves [--seeds 20]

Each world is calibrated exactly as a user's run is (``pipeline.calibrate_dataset``: the
diagnosis, the verdict, the replication), then targets spread over the sheet are planned with
the calibrated model (``plan_targets``, both elbows and approach sides, the stated
``std_mm`` of ``plan.uncertainty.target_std``) and landed on the world's true robot
(its effects and its repeatability, never the estimator's model). Printed per world kind:

- ``in95``: the fraction of real misses inside the stated 95 % bound (the 95 % radius of a
  circular normal error of per-axis std ``std_mm``: 2.448 std_mm); goal 0.90-0.99;
- ``ratio``: the real per-axis RMS miss over the stated (RMS of ``std_mm``); goal 0.7-1.4;
- ``in_expected``: the fraction inside the verdict's ``expected_target_error_mm``;
- the verdicts (ready / check / not reliable) and the halves' agreement.

Kinematic worlds (default, fast): a robot drawn at random around the SM5 (links +-2 mm,
zeros +-1 deg, base +-10 mm), its repeatability 0.004-0.02 mm per axis, the informative plan
with 8 repeats, marks measured to a stated 0.003-0.008 mm: ``clean`` (no hidden effect) and
``effect`` (one of backlash, gear scale, cyclic error, sheet shrink, at random sizes).
``--render``: the renderer's scenes (renders/*.yaml) with new seeds, photographed and
measured (clean and a gear-scale error seen from six places, the print off its layout seen
from six places or from one fixed camera, a clean world from one place): slow, a few seeds
each. ``--halves``: the replication's split against a model that
misses an effect (the elbows against marks taken alternately; the figure in
estimate/replicate.py's docstring).
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vision_cal.dataset.calibration import load_calibration  # noqa: E402
from vision_cal.dataset.covariance import load_covariance  # noqa: E402
from vision_cal.dataset.session import Sheet, SheetMarker  # noqa: E402
from vision_cal.estimate.verdict import R95_PER_STD  # noqa: E402
from vision_cal.model.kinematics import ScaraParams  # noqa: E402
from vision_cal.plan.calibration_plan import informative_plan  # noqa: E402
from vision_cal.plan.compensate import plan_targets  # noqa: E402
from vision_cal.plan.uncertainty import target_std  # noqa: E402
from vision_cal.world.truth_model import TrueRobot  # noqa: E402
from vision_cal.actions.pipeline import calibrate_dataset  # noqa: E402

SM5 = ScaraParams(344.05, 259.87, -2.57, -8.13, -424.26, -230.35)
NOMINAL = ScaraParams(350.0, 260.0, 0.0, 0.0, -400.0, -250.0)
ROOT = Path(__file__).resolve().parents[1]


def make_sheet(bottom_left=(-150.0, -520.0), size=(594.0, 420.0)) -> Sheet:
    """An A2 sheet in the SM5's reach with a 3 x 3 grid of 40 mm ArUco squares (where the
    plan may put marks; the kinematic world has no photos)."""
    x0, y0 = bottom_left
    markers = []
    for fx in (0.05, 0.45, 0.85):
        for fy in (0.05, 0.45, 0.8):
            a, b = x0 + fx * size[0], y0 + fy * size[1]
            markers.append(SheetMarker(len(markers), np.array(
                [[a, b + 40.0], [a + 40.0, b + 40.0], [a + 40.0, b], [a, b]])))
    return Sheet("DICT_5X5_100", tuple(markers), size, bottom_left)


def random_effect(rng) -> list[dict]:
    """One hidden effect of the library, at a random size."""
    k = rng.integers(5)
    j = int(rng.integers(1, 3))
    if k == 0:
        return [{"name": "joint_backlash", "joint": j, "deg": float(rng.uniform(0.03, 0.2))}]
    if k == 1:
        return [{"name": "joint_scale", "joint": j,
                 "scale": float(rng.choice([-1, 1]) * rng.uniform(0.0005, 0.004))}]
    if k == 2:
        return [{"name": "joint_cyclic", "joint": j, "harmonic": int(rng.integers(1, 3)),
                 "deg": float(rng.uniform(0.02, 0.1)), "phase_deg": float(rng.uniform(0, 360))}]
    if k == 3:
        s = float(rng.uniform(0.001, 0.003))
        return [{"name": "sheet_affine", "matrix": [[1 + s, 0.0], [0.0, 1.0]]}]
    return [{"name": "joint_backlash", "joint": 2, "deg": float(rng.uniform(0.05, 0.15))},
            {"name": "joint_scale", "joint": 1, "scale": float(rng.uniform(0.001, 0.003))}]


def kinematic_world(kind: str, seed: int, out: Path):
    """A session of marks the true robot drew (``measured_mm`` with their stated noise) in
    ``out``; returns (true robot, its repeatability, the sheet)."""
    rng = np.random.default_rng(seed)
    truth_p = ScaraParams(SM5.L1_mm + rng.uniform(-2, 2), SM5.L2_mm + rng.uniform(-2, 2),
                          SM5.z1_deg + rng.uniform(-1, 1), SM5.z2_deg + rng.uniform(-1, 1),
                          SM5.base_x_mm + rng.uniform(-10, 10),
                          SM5.base_y_mm + rng.uniform(-10, 10))
    effects = [] if kind == "clean" else random_effect(rng)
    truth = TrueRobot.from_json(truth_p.to_json(), effects)
    rep = float(rng.uniform(0.004, 0.02))
    sig = float(rng.uniform(0.003, 0.008))
    sheet = make_sheet()
    plan = informative_plan(truth_p, sheet, rng=seed, n_repeats=8)
    q = np.array([m.joints_deg for m in plan])
    s = np.array([m.approach for m in plan], float)
    xy = truth.pen_mm(q, s) + rng.normal(0, rep, q.shape) + rng.normal(0, sig, q.shape)
    marks = [dict(m.to_json(), measured_mm=p.tolist(), measured_sigma_mm=sig)
             for m, p in zip(plan, xy)]
    out.mkdir(parents=True, exist_ok=True)
    (out / "session.json").write_text(json.dumps(
        {"format": "vision-cal/1", "robot": NOMINAL.to_json(), "marks": marks}))
    return truth, rep, sheet.extent_mm


def land_targets(cal_path: Path, truth: TrueRobot, rep: float, extent, rng,
                 n: int = 40) -> dict:
    """``n`` targets on the sheet planned with the calibration (both elbows and approach
    sides), landed on ``truth`` with its repeatability: the misses (N, 2), the stated
    ``std_mm`` (N,), the verdict's figures."""
    model, doc = load_calibration(cal_path)
    cov = load_covariance(doc, model, file=str(cal_path))
    x0, y0, x1, y1 = extent
    xy = np.column_stack([rng.uniform(x0 + 20, x1 - 20, n), rng.uniform(y0 + 20, y1 - 20, n)])
    miss, std, cal = [], [], []
    for elbow in (1, -1):
        for app in ((1, 1), (-1, -1), (1, -1)):
            ok = [p for p in plan_targets(model, [f"t{i}" for i in range(n)], xy, elbow=elbow,
                                          approach=app) if p.status == "ok"]
            if not ok:
                continue
            q = np.array([p.q_deg for p in ok])
            a = np.array([p.approach for p in ok], float)
            t = np.array([p.target_mm for p in ok])
            st = target_std(model, cov, q, a, t, doc)
            landed = truth.pen_mm(q, a) + rng.normal(0, rep, q.shape)
            miss.append(landed - t)
            std.append(st.total_mm)
            cal.append(st.calibration_mm)
    v = doc["verdict"]
    return {"miss": np.concatenate(miss), "std": np.concatenate(std),
            "cal": np.concatenate(cal),
            "expected": v.get("expected_target_error_mm"), "status": v["status"],
            "agree": (doc.get("replication") or {}).get("agree")}


def summarise(name: str, results: list[dict]) -> dict:
    miss = np.concatenate([r["miss"] for r in results])
    std = np.concatenate([r["std"] for r in results])
    err = np.hypot(*miss.T)
    in95 = float(np.mean(err < R95_PER_STD * std))
    ratio = float(np.sqrt(np.mean(miss**2)) / np.sqrt(np.mean(std**2)))
    inexp = float(np.mean(np.concatenate([np.hypot(*r["miss"].T) < r["expected"]
                                          for r in results if r["expected"] is not None])))
    per_world = [float(np.sqrt(np.mean(r["miss"]**2)) / np.sqrt(np.mean(r["std"]**2)))
                 for r in results]
    status = {k: sum(r["status"] == k for r in results) for k in ("ready", "check",
                                                                  "not reliable")}
    agree = sum(bool(r["agree"]) for r in results)
    cal = np.concatenate([r["cal"] for r in results])
    old95 = float(np.mean(err < R95_PER_STD * cal))
    old_ratio = float(np.sqrt(np.mean(miss**2)) / np.sqrt(np.mean(cal**2)))
    print(f"{name:<18} worlds {len(results):3d} targets {len(err):5d}  in95 {in95:.3f}  "
          f"ratio {ratio:.2f} (worlds {np.percentile(per_world, 10):.2f}-"
          f"{np.percentile(per_world, 90):.2f})  in_expected {inexp:.3f}  verdicts "
          f"{status['ready']}/{status['check']}/{status['not reliable']}  halves agree "
          f"{agree}/{len(results)}; the covariance alone (std_mm before #37): in95 "
          f"{old95:.3f}, ratio {old_ratio:.1f}", flush=True)
    return {"in95": in95, "ratio": ratio, "in_expected": inexp, "status": status}


def kinematic(seeds: int, first: int) -> None:
    for kind in ("clean", "effect"):
        res = []
        for seed in range(first, first + seeds):
            with tempfile.TemporaryDirectory() as d:
                d = Path(d)
                truth, rep, ext = kinematic_world(kind, seed + (0 if kind == "clean" else 100000),
                                                  d / "in")
                calibrate_dataset(d / "in", out_dir=d / "out")
                res.append(land_targets(d / "out" / "calibration.json", truth, rep, ext,
                                        np.random.default_rng(seed)))
        summarise(f"kinematic {kind}", res)


# ------------------------------------------------------------------------------- render

#: six camera places, as renders/printed_off_six.yaml photographs its sheet
SIX_PLACES = {"n_views": 6, "tilt_deg": [8.0, 20.0], "moving": True}
#: the render worlds: name -> (scene file, camera overrides)
SCENES = {"clean_six": ("clean", SIX_PLACES), "effect_six": ("scale_j2", SIX_PLACES),
          "printed_off_six": ("printed_off_six", {}),
          "printed_off_fixed": ("printed_off_fixed", {}), "clean_fixed": ("clean", {})}


def render_world(name: str, seed: int, out: Path):
    """The world ``name`` (:data:`SCENES`: a scene file with a new seed and its camera's
    places), lighter (1600 x 1200 photos, 20 + 6 marks), rendered into ``out``; returns
    (true robot, repeatability, the paper's extent)."""
    import yaml

    from vision_cal.estimate.paper import pilot_params
    from vision_cal.world.dataset import render_dataset
    from vision_cal.world.scene import scene_from_dict

    scene, places = SCENES[name]
    raw = copy.deepcopy(yaml.safe_load((ROOT / "renders" / f"{scene}.yaml").read_text())
                        or {})
    raw["seed"] = seed
    raw.setdefault("camera", {}).update(places)
    raw.setdefault("plan", {}).update({"n_calibration": 20, "n_validation": 6})
    cam = raw.setdefault("camera", {})
    f = float(cam.get("f_px", 2600.0)) * 1600.0 / float((cam.get("size_px") or [2400])[0])
    cam.update({"size_px": [1600, 1200], "f_px": f})
    render_dataset(scene_from_dict(raw), out, pilot=pilot_params, jobs=1)
    t = json.loads((out / "truth.json").read_text())
    truth = TrueRobot.from_json(t["params"], [e for e in t.get("effects", [])
                                              if e["name"] not in ("lens_distortion",
                                                                   "sheet_height")])
    s = json.loads((out / "session.json").read_text())["sheet"]
    x0, y0 = s.get("bottom_left_mm") or (0.0, 0.0)
    w, h = s["size_mm"]
    return truth, float(t.get("repeatability_mm", 0.01)), (x0, y0, x0 + w, y0 + h)


def render(seeds: int, first: int, scenes) -> None:
    for name in scenes:
        res = []
        for seed in range(first, first + seeds):
            with tempfile.TemporaryDirectory() as d:
                d = Path(d)
                truth, rep, ext = render_world(name, seed, d / "in")
                calibrate_dataset(d / "in", out_dir=d / "out", jobs=1)
                res.append(land_targets(d / "out" / "calibration.json", truth, rep, ext,
                                        np.random.default_rng(seed)))
            print(f"  {name} seed {seed}: status {res[-1]['status']}, ratio "
                  f"{np.sqrt(np.mean(res[-1]['miss']**2)) / np.sqrt(np.mean(res[-1]['std']**2)):.2f}",
                  flush=True)
        summarise(f"render {name}", res)


# ------------------------------------------------------------------------------- halves

def halves(seeds: int, first: int) -> None:
    """The split's power: a model that misses a gear-scale or cyclic error, and a right one,
    replicated by the elbows and by marks taken alternately."""
    from vision_cal.estimate import replicate as rp
    from vision_cal.model.lsq import Fit
    from vision_cal.model.robot import JointBacklash, RobotModel

    bl = [{"name": "joint_backlash", "joint": 2, "deg": 0.1}]
    cases = {"right model": (bl, (JointBacklash(2),)),
             "scale missed": (bl + [{"name": "joint_scale", "joint": 1, "scale": 0.003}],
                              (JointBacklash(2),)),
             "cyclic missed": (bl + [{"name": "joint_cyclic", "joint": 1, "harmonic": 1,
                                      "deg": 0.05, "phase_deg": 30.0}], (JointBacklash(2),))}
    splits = rp.candidate_splits
    for name, (eff, meff) in cases.items():
        rows = {"elbows": [], "alternate": []}
        for seed in range(first, first + seeds):
            rng = np.random.default_rng(seed)
            plan = [m for m in informative_plan(NOMINAL, make_sheet(), rng=seed)
                    if m.role == "calibration"]
            q = np.array([m.joints_deg for m in plan])
            s = np.array([m.approach for m in plan], float)
            xy = TrueRobot.from_json(SM5.to_json(), eff).pen_mm(q, s) + rng.normal(
                0, np.hypot(0.005, 0.01), q.shape)
            sig = np.full(len(q), 0.005)
            fit = Fit.from_estimate(q, xy, approach=s, model=RobotModel(SM5, meff),
                                    sigma_mm=sig, robust=False)
            for key, pick in (("elbows", 0), ("alternate", 2)):
                rp.candidate_splits = (lambda *a, _p=pick: [splits(*a)[_p]])
                try:
                    r = rp.replicate(fit.model, q, xy, s, sig, residual_scale=fit.residual_scale)
                finally:
                    rp.candidate_splits = splits
                rows[key].append(r["params"]["chi2_dof"] if r["agree"] is not None else np.nan)
                rows[key + " disagree"] = rows.get(key + " disagree", 0) + (r["agree"] is False)
        print(f"{name:<14} elbows: chi2/dof median {np.nanmedian(rows['elbows']):.2f}, "
              f"disagree {rows.get('elbows disagree', 0)}/{seeds}; alternate marks: median "
              f"{np.nanmedian(rows['alternate']):.2f}, disagree "
              f"{rows.get('alternate disagree', 0)}/{seeds}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=None)
    ap.add_argument("--first-seed", type=int, default=5000)
    ap.add_argument("--render", action="store_true")
    ap.add_argument("--scenes", default=",".join(SCENES), help=", ".join(SCENES))
    ap.add_argument("--halves", action="store_true")
    a = ap.parse_args()
    if a.render:
        render(a.seeds or 3, a.first_seed, a.scenes.split(","))
    elif a.halves:
        halves(a.seeds or 20, a.first_seed)
    else:
        kinematic(a.seeds or 20, a.first_seed)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
