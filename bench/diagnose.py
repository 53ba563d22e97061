"""Diagnosis hit rate and false-claim rate over the full grid of effects, sizes and seeds.

Usage: .venv/bin/python bench/diagnose.py [--seeds 10] [--sigma 0.012]

Each case: the SM5-like truth (bench default) with one hidden effect (or none), the
informative plan's pose spread (30 calibration + 8 validation marks, balanced approach
signs), marks measured with isotropic noise ``sigma`` (mm, per axis: robot repeatability
and camera measurement together). A hit is the right effect on the right joint with its
size within 20 %, and the base parameters within 0.05 mm and 0.01 deg; a false claim is
any effect named on clean data. Printed as a table; the time per diagnosis is given as a
ratio against one plain base-model least-squares fit (scipy, numeric Jacobian) in the same
process.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.optimize import least_squares

from vision_cal.diagnose.select import diagnose
from vision_cal.kinematics import ScaraParams, forward
from vision_cal.model import JointBacklash, JointCyclic, JointScale, RobotModel, SheetAffine

TRUTH = ScaraParams(344.05, 259.87, -2.57, -8.13, -424.26, -230.35)


def grid():
    for j in (1, 2):
        for d in (0.05, 0.1, 0.2):
            yield f"backlash j{j} {d} deg", JointBacklash(joint=j, deg=d), "deg", d
        for s in (0.001, 0.003, -0.005):
            yield f"scale j{j} {100 * s:+.1f} %", JointScale(joint=j, scale=s), "scale", s
        for h in (1, 2):
            for d in (0.03, 0.1):
                yield (f"cyclic j{j} h{h} {d} deg", JointCyclic(joint=j, harmonic=h, deg=d,
                                                                 phase_deg=35.0), "deg", d)
    for ax, s in (("x", 0.001), ("x", 0.003), ("y", 0.002)):
        m = [[1.0 + s, 0.0], [0.0, 1.0]] if ax == "x" else [[1.0, 0.0], [0.0, 1.0 + s]]
        yield f"sheet shrink {ax} {100 * s:.1f} %", SheetAffine(tuple(map(tuple, m))), "matrix", s


def plan(rng, n=38):
    q = np.column_stack([rng.uniform(-80, 40, n), rng.uniform(-140, 140, n)])
    s = np.tile([[1, 1], [-1, -1], [1, -1], [-1, 1]], (n // 4 + 1, 1))[:n]
    return q, rng.permutation(s).astype(float)


def hit(effect, key, size, found, p) -> bool:
    if len(found) != 1 or found[0]["name"] != effect.name:
        return False
    e = found[0]
    if key == "matrix":
        got = e["matrix"][0][0] - 1 if e["matrix"][0][0] != 1 else e["matrix"][1][1] - 1
        axis_ok = (e["matrix"][0][0] != 1) == (effect.M[0, 0] != 1)
        return axis_ok and abs(got - size) <= 0.2 * abs(size)
    if e.get("joint") != effect.joint or e.get("harmonic") != getattr(effect, "harmonic", None):
        return False
    base_ok = (abs(p.L1_mm - TRUTH.L1_mm) < 0.05 and abs(p.L2_mm - TRUTH.L2_mm) < 0.05 and
               abs(p.z1_deg - TRUTH.z1_deg) < 0.01 and abs(p.z2_deg - TRUTH.z2_deg) < 0.01)
    return base_ok and abs(e[key] - size) <= 0.2 * abs(size)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--sigma", type=float, default=0.012, help="mark noise per axis, mm")
    a = ap.parse_args()
    rows, t_diag, t_base = [], [], []
    cases = [("clean", None, None, None)] + list(grid())
    false_claims = clean_runs = 0
    for name, effect, key, size in cases:
        hits = 0
        for seed in range(a.seeds):
            rng = np.random.default_rng(1000 + seed)
            q, s = plan(rng)
            truth = RobotModel(TRUTH, (effect,) if effect is not None else ())
            xy = truth.predict(q, s) + rng.normal(0, a.sigma, q.shape)
            t0 = time.perf_counter()
            d = diagnose(q[:30], xy[:30], s[:30], q_val=q[30:], xy_val=xy[30:],
                         approach_val=s[30:])
            t_diag.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            least_squares(lambda v: (forward(ScaraParams.from_vector(v), q[:30]) - xy[:30]).ravel(),
                          d.base_fit.initial.vector)
            t_base.append(time.perf_counter() - t0)
            found = [e for e in d.effects_json() if e["name"] != "unexplained"]
            if effect is None:
                clean_runs += 1
                false_claims += bool(found)
                hits += not found
            else:
                hits += hit(effect, key, size, found, d.final_fit.params)
        rows.append((name, hits, a.seeds))
    print(f"diagnosis grid: {len(cases)} cases x {a.seeds} seeds, sigma {a.sigma} mm per axis")
    for name, h, n in rows:
        print(f"  {name:<28} {h:>3}/{n}")
    total = sum(h for nm, h, n in rows if nm != "clean")
    count = sum(n for nm, h, n in rows if nm != "clean")
    print(f"hit rate: {total}/{count} = {100 * total / count:.1f} %")
    print(f"false-claim rate on clean data: {false_claims}/{clean_runs} = "
          f"{100 * false_claims / clean_runs:.1f} %")
    print(f"time per diagnosis: {1000 * np.median(t_diag):.1f} ms = "
          f"{np.median(t_diag) / np.median(t_base):.1f}x one plain scipy base fit "
          f"({1000 * np.median(t_base):.2f} ms)")


if __name__ == "__main__":
    main()
