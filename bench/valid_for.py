"""Issue 29 figures: the README rehearsal's targets planned beyond what a calibration saw.

Usage: .venv/bin/python bench/valid_for.py [--out /tmp/bench-valid-for] [--seed 1]

Runs the README's "Rehearse it first" block (tests/test_rehearsal.py reads it; ``--seed``
replaces the simulated robot's), then plans its six targets from the pilot's calibration
and from the informative plan's, with the approach side each saw (+1 +1) and the other
(-1 -1), and with orientations (``theta_deg`` 0 / 90 / 180: joint 4 turned), each on the
simulated robot (``vision-cal simulate``). For each: the exit code without ``--force``
(2: refused, outside ``valid_for``; what it said) and, with it, the true miss of the
targets (truth.json). Also the informative plan's controller offsets against the robot
file's zeros minus the true ones.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shlex
import shutil
import sys
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

THETA = ("id,x_mm,y_mm,theta_deg\nt1,30,-60,0\nt2,80,40,90\nt3,-120,80,180\n"
         "t4,-200,-100,0\nt5,150,-120,90\nt6,50,120,180\n")


def vc(argv: list[str], cwd: Path) -> tuple[int, str]:
    from vision_cal.commands.main import main

    old = os.getcwd()
    os.chdir(cwd)
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            rc = main(argv + ["-q"])
    finally:
        os.chdir(old)
    return rc, err.getvalue()


def miss(d: Path, hits: str) -> np.ndarray:
    import csv

    truth = json.loads((d / hits / "truth.json").read_text())["marks"]
    rows = list(csv.DictReader((d / "targets.csv").read_text().splitlines()))
    return np.array([np.hypot(*np.subtract(truth[r["id"]], (float(r["x_mm"]),
                                                             float(r["y_mm"]))))
                     for r in rows if r["id"] in truth])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="/tmp/bench-valid-for")
    ap.add_argument("--seed", type=int, default=None)
    a = ap.parse_args()
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    from tests.test_rehearsal import readme_commands

    d = Path(a.out)
    shutil.rmtree(d, ignore_errors=True)
    d.mkdir(parents=True)
    for line in readme_commands():
        if line.startswith("vision-cal "):
            rc, err = vc(shlex.split(line)[1:], d)
            if rc != 0:
                raise SystemExit(f"{line}: exit {rc}: {err}")
            if a.seed is not None and "robot-template --simulated" in line:
                t = yaml.safe_load((d / "true_robot.yaml").read_text())
                t["seed"] = a.seed
                (d / "true_robot.yaml").write_text(yaml.safe_dump(t))
        else:
            import subprocess

            subprocess.run(line, shell=True, cwd=d, check=True)
    (d / "targets_theta.csv").write_text(THETA)
    robot = yaml.safe_load((d / "robot.yaml").read_text())
    truth = json.loads((d / "plan" / "truth.json").read_text())["params"]
    rep = json.loads((d / "cal" / "report.json").read_text())
    for o in rep["actions"]["controller_offsets"]:
        j = o["joint"] - 1
        want = robot["joint_zero_deg"][j] - truth["joint_zero_deg"][j]
        print(f"report: add {o['add_to_offset_deg']:+.4f} deg to joint {o['joint']}'s "
              f"offset; robot file minus truth {want:+.4f} (off by "
              f"{o['add_to_offset_deg'] - want:+.4f})")
    for cal in ("pilot_cal", "cal"):
        v = json.loads((d / cal / "calibration.json").read_text())["verdict"]
        print(f"{cal}: verdict {v['status']} (inside valid_for: "
              f"{v.get('within_valid_for') or v['status']})")
        for what, targets, extra in (("approach +1 +1", "targets.csv", ["--approach", "1", "1"]),
                                     ("approach -1 -1", "targets.csv", ["--approach", "-1", "-1"]),
                                     ("theta 0/90/180", "targets_theta.csv", [])):
            tag = f"{cal}_{what.replace(' ', '_').replace('/', '-')}"
            argv = ["plan", f"{cal}/calibration.json", targets, "-o", f"{tag}.csv",
                    "--program", "spel", "--robot", "robot.yaml", *extra]
            rc, err = vc(argv, d)
            said = (err.strip().splitlines() or [""])[0]
            field = said.split("valid_for.")[1].split(":")[0] if "valid_for." in said else ""
            if rc != 0:
                rc2, err2 = vc(argv + ["--force"], d)
                assert rc2 == 0
                # every reason the forced plan stated (the refusal names the first)
                field = "; ".join(ln.split("(written because of --force): ")[1][:60] + "..."
                                  for ln in err2.splitlines() if "because of --force" in ln)
            rc3, err3 = vc(["simulate", f"{tag}.prg", "--truth", "true_robot.yaml", "--sheet",
                            "sheet/sheet.json", "--targets", "targets.csv", "--out",
                            f"hits_{tag}/"], d)
            assert rc3 == 0, err3
            m = miss(d, f"hits_{tag}")
            print(f"  {what:<16} plan exit {rc}{' (' + field + ')' if field else ''}"
                  f"{', with --force' if rc else ''}: {len(m)} targets miss RMS "
                  f"{np.sqrt(np.mean(m**2)):.4f} mm, max {m.max():.4f} mm on the simulated robot")


if __name__ == "__main__":
    main()
