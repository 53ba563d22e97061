"""The README's "Calibrate your robot" page on a simulated robot: time per step, accuracy.

Usage: .venv/bin/python bench/walkthrough.py [--out /tmp/bench-walkthrough]

The user's page, step by step, through the command line: print the sheet (`vision-cal
sheet`), design the pilot (`vision-cal design`), the robot draws it (a simulated true
robot - SM5 with a hidden 0.1 deg backlash in joint 2, placed 28 mm and several degrees
away from the robot file's guess - follows the SPEL+ program, read back by the tests'
parser, through the simulated sliding-mode controller and arm dynamics), photograph the
finished sheet (rendered with the printed sheet's own raster, sheet.png), calibrate the
pilot, design the informative plan from it, draw (on the same sheet), photograph,
calibrate with --report, plan targets with --program spel, and run that program on the
true robot. Prints seconds per step, the compensated targets' RMS and max miss on the true
robot (mm) and the RMS of plan.csv's predicted std_mm, and checks the bounds the test of
this page used to (0.05 mm RMS; the misses within 3x the predicted std, which holds the
robot's repeatability since issue 37). The test suite runs the same page once, from the shell, as
tests/test_rehearsal.py (`vision-cal simulate` standing in for the robot, the same
controller, program and printed raster): not twice.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.design.test_programs import parse_spel  # noqa: E402
from vision_cal.commands.main import main as cli_main  # noqa: E402
from vision_cal.model.kinematics import ScaraParams  # noqa: E402
from vision_cal.plan.calibration_plan import PlannedMark  # noqa: E402
from vision_cal.world.truth_model import TrueRobot  # noqa: E402

ROBOT = ROOT / "fixtures" / "robot_sm5.yaml"
TRUTH = TrueRobot.from_json(
    {"L1_mm": 344.05, "L2_mm": 259.87, "joint_zero_deg": [-2.57, -8.13],
     "base_mm": [-420.0, -230.0]}, [{"name": "joint_backlash", "joint": 2, "deg": 0.1}])
REPEATABILITY_MM = 0.01
PHOTO_PX = (1600, 1200)
F_PX = 1750.0
TEXTURE_PX_PER_MM = 6.0


def cli(*args) -> None:
    rc = cli_main([str(a) for a in args])
    if rc != 0:
        raise SystemExit(f"vision-cal {' '.join(map(str, args))} exited {rc}")


def follow_program(prg: Path, *, up: float, down: float) -> list[PlannedMark]:
    """What a controller does with the SPEL+ program: the pen-down points in order, each
    with the points driven through since the previous pen-up (its via points)."""
    ops = [a for op, a, _ in parse_spel(prg.read_text())["ops"] if op == "go"]
    marks, path, k = [], [], 0
    for a in ops:
        q = (a[0], a[1])
        if a[2] == down:
            vias = tuple(p for p in path[:-1])
            marks.append(PlannedMark(f"m{k:03d}", q, "calibration", (1, 1), vias))
            k += 1
            path = []
        else:
            if not path or path[-1] != q:
                path.append(q)
    return marks


def draw(prg: Path, rng):
    """The true robot follows the program: the simulated sliding-mode controller drives
    the arm's dynamics through every point (the backlash is real gear play there); where
    the pen really marks (sheet mm)."""
    from vision_cal.dataset.robot import load_robot_file
    from vision_cal.world.drawing import draw_marks, simulated_world

    robot = load_robot_file(ROBOT)
    up, down = robot.require_pen_heights()
    marks = follow_program(prg, up=up, down=down)
    source, model = simulated_world(TRUTH, controller="smc", rng=rng)
    return draw_marks(model, marks, home_deg=robot.nominal.home_deg,
                      repeatability_mm=REPEATABILITY_MM, joint_source=source, rng=rng)


def photograph(folder: Path, sheet_dir: Path, world, photographer, rng, *, n: int,
               also_xy_mm=np.zeros((0, 2))) -> list[str]:
    """``n`` photos of the finished sheet from random views above it, into ``folder``
    (``also_xy_mm``: earlier marks already on the sheet)."""
    import cv2

    from vision_cal.world.camera import camera_matrix, default_views
    from vision_cal.world.printed import load_printed_sheet, printed_texture

    printed = load_printed_sheet(sheet_dir / "sheet.json")
    sheet = printed.sheet
    tex = printed_texture(printed, marks_xy_mm=np.vstack([also_xy_mm, world.xy_mm]),
                          mark_diameters_mm=1.2, rng=rng)
    K = camera_matrix(size_px=PHOTO_PX, f_px=F_PX)
    views = default_views(sheet, n=n, size_px=PHOTO_PX, K=K, tilt_deg=(0.0, 12.0), rng=rng,
                          fill=0.96, target_jitter=0.02)
    files = []
    for i, T in enumerate(views):
        rgb = photographer.photograph(tex, extent_mm=sheet.extent_mm, T_cam_sheet=T,
                                      vignetting=0.15, noise_sigma=1.5, rng=rng)
        name = f"IMG_{i + 1:04d}.png"
        cv2.imwrite(str(folder / name), np.ascontiguousarray(rgb[:, :, ::-1]))
        files.append(name)
    return files


def walkthrough(tmp: Path) -> dict:
    from vision_cal.dataset.csvio import read_plan, write_targets
    from vision_cal.dataset.session import load_sheet_file
    from vision_cal.actions.loop import default_targets
    from vision_cal.world.camera import camera_matrix
    from vision_cal.world.photo import Photographer

    tmp.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(2026)
    photographer = Photographer(size_px=PHOTO_PX, K=camera_matrix(size_px=PHOTO_PX, f_px=F_PX))
    t0 = time.perf_counter()
    stages = {}

    def stage(name):
        stages[name] = time.perf_counter() - t0 - sum(stages.values())

    sheet_dir = tmp / "sheet"
    cli("sheet", "--size", "A2", "--png-dpi", 25.4 * TEXTURE_PX_PER_MM, "--out", sheet_dir, "-q")
    stage("sheet")
    cli("design", ROBOT, "--sheet", sheet_dir / "sheet.json", "--out", tmp / "pilot", "-q")
    stage("design pilot")
    pilot_world = draw(tmp / "pilot" / "program.prg", rng)
    photograph(tmp / "pilot", sheet_dir, pilot_world, photographer, rng, n=2)
    stage("draw + photograph pilot")
    cli(tmp / "pilot", "--out", tmp / "pilot_cal", "-q")
    stage("calibrate pilot")
    cli("design", ROBOT, "--sheet", sheet_dir / "sheet.json", "--out", tmp / "plan",
        "--pilot", tmp / "pilot_cal" / "calibration.json", "-q")
    stage("design informative")
    world = draw(tmp / "plan" / "program.prg", rng)
    # the same sheet, not moved: the pilot's marks are on it too
    photograph(tmp / "plan", sheet_dir, world, photographer, rng, n=3,
               also_xy_mm=pilot_world.xy_mm)
    stage("draw + photograph plan")
    cli(tmp / "plan", "--out", tmp / "cal", "--report", "-q")
    stage("calibrate --report")
    cal = json.loads((tmp / "cal" / "calibration.json").read_text())
    sheet = load_sheet_file(sheet_dir / "sheet.json")
    ids, xy = default_targets(sheet, ScaraParams.from_json(cal["params"]), n_grid=20, n_path=6)
    # the targets where the calibration was calibrated (valid_for: the joints its marks
    # covered); plan refuses one beyond them (tests/dataset/test_valid_for.py)
    from vision_cal.dataset.valid_for import check as check_valid_for
    from vision_cal.model.kinematics import inverse

    qt = inverse(ScaraParams.from_json(cal["params"]), np.asarray(xy), elbow=1)
    beyond = {i for o in check_valid_for(cal["valid_for"], ids=ids, joints_deg=qt.tolist())
              for i in o.ids}
    keep = [i not in beyond for i in ids]
    ids, xy = [i for i, k in zip(ids, keep) if k], np.asarray(xy)[keep]
    write_targets(tmp / "targets.csv", ids, xy)
    cli("plan", tmp / "cal" / "calibration.json", tmp / "targets.csv", "-o", tmp / "plan.csv",
        "--program", "spel", "--robot", ROBOT, "-q")
    stage("plan targets + program")
    photographer.close()
    hit = draw(tmp / "plan.prg", np.random.default_rng(7))
    pid, q, s = read_plan(tmp / "plan.csv")
    import csv

    rows = csv.DictReader((tmp / "plan.csv").read_text().splitlines())
    std = {r["id"]: float(r["std_mm"]) for r in rows if r["status"] == "ok"}
    return {"std_mm": np.array([std[i] for i in pid]),"tmp": tmp, "stages_s": stages, "total_s": time.perf_counter() - t0, "cal": cal,
            "targets": dict(zip(ids, xy)), "plan_ids": pid, "hit_xy": hit.xy_mm,
            "pilot_world": pilot_world, "world": world}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="/tmp/bench-walkthrough")
    a = ap.parse_args()
    w = walkthrough(Path(a.out))
    targets = np.array([w["targets"][i] for i in w["plan_ids"]])
    err = np.hypot(*(w["hit_xy"] - targets).T)
    rms = float(np.sqrt(np.mean(err**2)))
    pred = float(np.sqrt(np.mean(w["std_mm"] ** 2)))
    for k, v in w["stages_s"].items():
        print(f"{k:<28}{v:8.1f} s")
    print(f"{'total':<28}{w['total_s']:8.1f} s")
    print(f"compensated targets on the true robot: RMS {rms:.4f} mm, max {err.max():.4f} mm "
          f"over {len(err)} targets; predicted std (per axis, RMS) {pred:.4f} mm; effects "
          f"found: {', '.join(e['name'] for e in w['cal']['effects']) or 'none'}")
    expected = pred   # std_mm holds the repeatability (issue 37)
    ok = (len(err) >= 0.9 * len(w["targets"]) and rms < 0.05
          and rms / np.sqrt(2) < 3 * expected
          and all(im["status"] == "ok" for im in w["cal"]["images"])
          and any(e["name"] == "joint_backlash" and e["joint"] == 2
                  for e in w["cal"]["effects"]))
    print("checks (RMS < 0.05 mm, misses within 3x predicted std_mm, every photo "
          f"used, backlash in joint 2 found): {'pass' if ok else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
