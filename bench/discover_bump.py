"""Does discovery claim a joint term for a local sheet bump? (issue: a local bump taken for a
global joint term.)

Two worlds per seed, on the kinematic model (no rendering), 46 marks drawn in order, noise
0.01 mm per axis, every mark's sigma given, k-fold CV (no validation marks) or every sixth
mark held out (``--val``):

    bump      the base robot plus a 0.15 mm bump, 80 mm wide, at the marks' median point
    joint     the same bump plus a real joint-1 term ``cos(q2)`` of ``--coef`` degrees

and counts how often the traced diagnosis holds a joint term of joint 1 or 2 (false on
``bump``), and how often it holds ``cos(q2)`` on joint 1 (right on ``joint``).

    python bench/discover_bump.py --seeds 20-29 [--val] [--coef 0.02]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.conftest import SM5, random_plan  # noqa: E402
from vision_cal.diagnose.discover import trace  # noqa: E402
from vision_cal.diagnose.select import diagnose  # noqa: E402
from vision_cal.render.truth_model import TrueRobot  # noqa: E402

N, SIGMA, MEAS = 46, 0.01, 0.003


def world(seed: int, *, bump: bool = True, coef: float = 0.0, n: int = N):
    """(q, s, t, xy): the marks of one world (see the module docstring)."""
    rng = np.random.default_rng(seed)
    q, s = random_plan(n, rng)
    t = np.linspace(0, 1, n)
    effects = ([{"name": "joint_terms", "joint": 1, "terms": [{"feature": "cos(q2)",
                                                               "coef": coef}]}]
               if coef else [])
    xy = TrueRobot.from_json(SM5.to_json(), effects).pen_mm(q, s, t=t) \
        + rng.normal(0, SIGMA, (n, 2))
    if bump:
        c = np.median(xy, axis=0)
        xy = xy + (0.15 * np.exp(-np.sum((xy - c) ** 2, axis=1) / (2 * 80.0**2)))[:, None] \
            * np.array([0.6, 0.8])
    return q, s, t, xy


def run(q, s, t, xy, *, val: bool = False):
    """The traced diagnosis of one world: (effect names, the selected terms, sheet seen)."""
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
    return joint, terms, sheet, tr.report.get("decision")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="20-29")
    ap.add_argument("--val", action="store_true")
    ap.add_argument("--coef", type=float, default=0.02)
    a = ap.parse_args(argv)
    lo, _, hi = a.seeds.partition("-")
    seeds = range(int(lo), int(hi or lo) + 1)
    false = found = 0
    for seed in seeds:
        jb, tb, sb, db = run(*world(seed), val=a.val)
        jj, tj, sj, dj = run(*world(seed, coef=a.coef), val=a.val)
        false += bool(jb)
        hit = "cos(q2)" in tj.get("joint1", [])
        found += hit
        print(f"seed {seed}: bump-only joint effects {jb} sheet {sb} ({db}) | "
              f"bump+cos(q2) {tj} found {hit} sheet {sj} ({dj})", flush=True)
    print(f"false joint effects on bump-only worlds: {false}/{len(seeds)}; "
          f"cos(q2) on joint 1 found: {found}/{len(seeds)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
