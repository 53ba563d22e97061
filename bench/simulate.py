"""Bench: simulating calibration plans (trajectory -> SMC/PD -> SCARA dynamics -> backlash).

Run: .venv/bin/python bench/simulate.py

Prints the wall time to simulate the default informative plan (30 + 8 marks, SMC, 1 kHz),
as a ratio against plain baselines run in the same process (sampling the same reference at
1 kHz with scipy's CubicSpline; an empty Python loop of the same number of steps), the
real-time factor, the paper plan's trajectory duration against the paper's 47.6 s, and the
tracking/settling figures of both controllers.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from scipy.interpolate import CubicSpline

from vision_cal.dataset.session import Sheet, SheetMarker
from vision_cal.model.kinematics import ScaraParams
from vision_cal.plan.calibration_plan import informative_plan, paper_plan
from vision_cal.plan.trajectory import plan_trajectory
from vision_cal.world.controller import PDController
from vision_cal.world.simulate import simulate_plan

NOMINAL = ScaraParams(350.0, 260.0, 0.0, 0.0, -400.0, -250.0)   # SM5 CAD, base a rough guess
PAPER_S = 47.6


def a2_sheet() -> Sheet:
    """A2 sheet in the SM5's reach, 3 x 3 grid of 40 mm ArUco squares."""
    x0, y0, w, h = -150.0, -520.0, 594.0, 420.0
    mk = []
    for fx in (0.05, 0.45, 0.85):
        for fy in (0.05, 0.45, 0.8):
            x, y = x0 + fx * w, y0 + fy * h
            mk.append(SheetMarker(len(mk), np.array([[x, y + 40], [x + 40, y + 40], [x + 40, y],
                                                     [x, y]], dtype=float)))
    return Sheet("DICT_5X5_100", tuple(mk), (w, h), (x0, y0))


def best_of(f, n=3):
    best, out = np.inf, None
    for _ in range(n):
        t = time.perf_counter()
        out = f()
        best = min(best, time.perf_counter() - t)
    return best, out


def main():
    if {"-h", "--help"} & set(sys.argv[1:]):   # the usage, not a run of minutes
        print(__doc__)
        return
    t_plan, plan = best_of(lambda: informative_plan(NOMINAL, a2_sheet(), rng=0), 3)
    band = (0.1, 0.05)
    t_smc, smc = best_of(lambda: simulate_plan(plan, backlash_deg=band, controller="smc"), 3)
    t_pd, pd = best_of(lambda: simulate_plan(plan, backlash_deg=band, controller="pd"), 1)
    pdm = simulate_plan(plan, backlash_deg=band,
                        controller=PDController(derivative_on_error=False))
    ref = smc.reference

    # baselines over the same simulated time at the same 1 kHz step
    t1k = np.arange(smc.n_steps + 1) * 1e-3
    knots = np.concatenate([[0.0], ref.knot_t_s[1:]])
    keep = np.concatenate([[True], np.diff(knots) > 0])
    cs = CubicSpline(knots[keep], ref.waypoints_deg[keep], bc_type="clamped")
    t_cs, _ = best_of(lambda: (cs(t1k), cs(t1k, 1), cs(t1k, 2)), 5)

    def empty_loop():
        x = 0.0
        for _ in range(smc.n_steps):
            x += 1e-3
        return x
    t_loop, _ = best_of(empty_loop, 3)

    s = np.array([m.approach for m in plan])
    print(f"informative plan: {len(plan)} marks "
          f"({sum(m.role == 'calibration' for m in plan)} calibration), built in "
          f"{t_plan * 1e3:.0f} ms")
    print(f"simulate_plan SMC, 1 kHz: {smc.n_steps} steps ({smc.duration_s:.1f} s simulated) "
          f"in {t_smc:.3f} s wall = {smc.duration_s / t_smc:.0f}x real time, "
          f"{t_smc / smc.n_steps * 1e6:.1f} us/step")
    print(f"  baseline scipy CubicSpline sampling of the reference at 1 kHz (q, qd, qdd): "
          f"{t_cs * 1e3:.2f} ms -> simulation costs {t_smc / t_cs:.0f}x")
    print(f"  baseline empty Python loop of {smc.n_steps} steps: {t_loop * 1e3:.2f} ms -> "
          f"simulation costs {t_smc / t_loop:.0f}x")
    print(f"simulate_plan PD: {pd.n_steps} steps ({pd.duration_s:.1f} s simulated, waits for "
          f"settling) in {t_pd:.3f} s wall")
    print(f"reference trajectory of the informative plan: {ref.duration_s:.2f} s "
          f"({len(ref.t_s)} samples every {ref.dt_s} s)")

    paper = plan_trajectory(paper_plan())
    print(f"paper's 5-mark plan: trajectory {paper.duration_s:.2f} s vs the paper's {PAPER_S} s "
          f"(ratio {paper.duration_s / PAPER_S:.3f}; limits 90/120 deg/s, 300/400 deg/s^2, "
          f"0.3 s dwell)")
    ps = simulate_plan(paper_plan(), backlash_deg=band)
    print(f"  simulated (SMC): {ps.duration_s:.2f} s, tracking rms {fmt(ps.tracking_rms_deg)} deg")

    for name, r in (("SMC", smc), ("PD", pd), ("PD (D on measurement)", pdm)):
        link_err = np.abs(r.link_deg - (r.motor_deg - s * np.array(band) / 2)).max(axis=0)
        print(f"{name}: tracking rms {fmt(r.tracking_rms_deg)} deg, max "
              f"{fmt(r.tracking_max_deg)} deg; settle residual max "
              f"{fmt(np.abs(r.settle_residual_deg).max(axis=0))} deg; extra settle wait mean "
              f"{r.settle_extra_s.mean():.3f} s max {r.settle_extra_s.max():.3f} s; arrivals as "
              f"planned {int(np.all(r.approach == s, axis=1).sum())}/{len(plan)}; link off "
              f"the lagging flank max {fmt(link_err)} deg")


def fmt(a):
    return "[" + ", ".join(f"{x:.2g}" for x in np.asarray(a)) + "]"


if __name__ == "__main__":
    main()
