"""Does discovery claim a joint term for a local sheet bump? (issue: a local bump taken for a
global joint term.)

Worlds per seed, on the kinematic model (no rendering), 46 marks drawn in order, noise
0.01 mm per axis, every mark's sigma given, k-fold CV (no validation marks) or every sixth
mark held out (``--val``):

    bump      the base robot plus a 0.15 mm bump, 80 mm wide, at the marks' median point
    joint     the same bump plus a real joint-1 term ``cos(q2)`` of ``--coef`` degrees
    backlash  the same bump plus a real joint-2 backlash of ``--band`` degrees
    cyclic    the same bump plus a real joint-1 cyclic term (harmonic 1) of ``--amp`` degrees

and counts how often the traced diagnosis holds a joint term of joint 1 or 2 or a library
effect (``joint_backlash``, ``joint_scale``, ``joint_cyclic``, ``sheet_affine``: false on
``bump``), and how often it holds the true effect (right on the others).

    python bench/discover_bump.py --seeds 20-29 [--val] [--coef 0.02] [--band 0.08] [--amp 0.03]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.conftest import SM5, random_plan  # noqa: E402
from vision_cal.estimate.discover import trace  # noqa: E402
from vision_cal.estimate.select import diagnose  # noqa: E402
from vision_cal.world.truth_model import TrueRobot  # noqa: E402

N, SIGMA, MEAS = 46, 0.01, 0.003


LIBRARY = ("joint_backlash", "joint_scale", "joint_cyclic", "sheet_affine")


def world(seed: int, *, bump: bool = True, coef: float = 0.0, n: int = N,
          effects: tuple = ()):
    """(q, s, t, xy): the marks of one world (see the module docstring); ``effects``: more
    truth.json effects."""
    rng = np.random.default_rng(seed)
    q, s = random_plan(n, rng)
    t = np.linspace(0, 1, n)
    effects = ([{"name": "joint_terms", "joint": 1, "terms": [{"feature": "cos(q2)",
                                                               "coef": coef}]}]
               if coef else []) + list(effects)
    xy = TrueRobot.from_json(SM5.to_json(), effects).pen_mm(q, s, t=t) \
        + rng.normal(0, SIGMA, (n, 2))
    if bump:
        c = np.median(xy, axis=0)
        xy = xy + (0.15 * np.exp(-np.sum((xy - c) ** 2, axis=1) / (2 * 80.0**2)))[:, None] \
            * np.array([0.6, 0.8])
    return q, s, t, xy


def run(q, s, t, xy, *, val: bool = False):
    """The traced diagnosis of one world: (joint effect names, the selected terms, sheet
    seen, the decision, the library effects claimed (name, joint, harmonic))."""
    n = len(q)
    cal = np.arange(n) % 6 != 5 if val else np.ones(n, bool)
    v = ~cal
    sig = np.full(n, np.hypot(MEAS, SIGMA))
    kw = dict(q_val=q[v], xy_val=xy[v], approach_val=s[v]) if val else {}
    ids = [f"m{i}" for i in range(cal.sum())]
    d = diagnose(q[cal], xy[cal], s[cal], sigma_mm=sig[cal], ids=ids, **kw)
    tr = trace(d, q[cal], xy[cal], s[cal], t[cal], sigma_mm=sig[cal], ids=ids, **kw)
    eff = tr.diagnosis.effects_json()
    terms = {f"joint{e['joint']}": [x["feature"] for x in e["terms"]]
             for e in eff if e["name"] == "joint_terms"}
    joint = [e["name"] + str(e.get("joint", "")) for e in eff
             if e["name"].startswith("joint_") and e.get("joint") in (1, 2)]
    sheet = bool((tr.diagnosis.unexplained or {}).get("sheet"))
    library = [(e["name"], e.get("joint"), e.get("harmonic")) for e in eff
               if e["name"] in LIBRARY]
    return joint, terms, sheet, tr.report.get("decision"), library


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="20-29")
    ap.add_argument("--val", action="store_true")
    ap.add_argument("--coef", type=float, default=0.02)
    ap.add_argument("--band", type=float, default=0.08)
    ap.add_argument("--amp", type=float, default=0.03)
    a = ap.parse_args(argv)
    lo, _, hi = a.seeds.partition("-")
    seeds = range(int(lo), int(hi or lo) + 1)
    false = false_lib = found = found_bl = found_cy = 0
    backlash = ({"name": "joint_backlash", "joint": 2, "deg": a.band},)
    cyclic = ({"name": "joint_cyclic", "joint": 1, "harmonic": 1, "deg": a.amp,
               "phase_deg": 30.0},)
    for seed in seeds:
        jb, tb, sb, db, lb = run(*world(seed), val=a.val)
        jj, tj, sj, dj, _ = run(*world(seed, coef=a.coef), val=a.val)
        *_, lbl = run(*world(seed, effects=backlash), val=a.val)
        *_, lcy = run(*world(seed, effects=cyclic), val=a.val)
        false += bool(jb)
        false_lib += bool(lb)
        hit = "cos(q2)" in tj.get("joint1", [])
        found += hit
        bl = ("joint_backlash", 2, None) in lbl
        cy = ("joint_cyclic", 1, 1) in lcy
        found_bl += bl
        found_cy += cy
        print(f"seed {seed}: bump-only joint effects {jb} library {lb} sheet {sb} ({db}) | "
              f"bump+cos(q2) {tj} found {hit} sheet {sj} ({dj}) | "
              f"bump+backlash2 {lbl} found {bl} | bump+cyclic1 {lcy} found {cy}", flush=True)
    n = len(seeds)
    print(f"false joint effects on bump-only worlds: {false}/{n}; false library effects: "
          f"{false_lib}/{n}; cos(q2) on joint 1 found: {found}/{n}; joint-2 backlash "
          f"found: {found_bl}/{n}; joint-1 cyclic found: {found_cy}/{n}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
