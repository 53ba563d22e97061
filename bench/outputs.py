"""Outputs unchanged: every JSON value of calibration.json and measurement.json of the demo,
the paper fixture and the tracker example, before and after a change (issue 41: a speed-up
changes no figure).

``save DIR [--code SRC]`` runs the cases with the vision_cal package of ``SRC`` (default this
checkout; e.g. ``git archive BASE | tar -x -C /tmp/base`` for the commit before the change)
and keeps their JSON files under ``DIR/<case>/``. ``compare DIR [--code SRC]`` runs them again
and prints, for each file, "identical" or every value that differs (its JSON path, both
values, and for numbers the relative difference); exit 1 when any differs.

The cases, each in a fresh output folder (no detection cache), one BLAS thread:

- ``demo``: ``vision-cal DIR --jobs 1`` on the demo's 38 photos (renders/default.yaml,
  rendered once into /tmp/vision-cal-bench-whole as ``bench/measure.py --whole`` does);
- ``paper`` and ``paper_lsq``: ``fixtures/paper_sm5`` with ``--method paper`` (``make demo``'s
  first step) and with the default least squares;
- ``tracker``: ``vision-cal calibrate fixtures/tracker_example/marks.csv --robot ...
  --sigma-mm 0.02`` (its README's command).

Usage::

    .venv/bin/python bench/outputs.py save /tmp/outputs-before --code /tmp/base
    .venv/bin/python bench/outputs.py compare /tmp/outputs-before
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEMO = Path("/tmp/vision-cal-bench-whole")
FILES = ("calibration.json", "measurement.json")
TRACKER = ROOT / "fixtures" / "tracker_example"


def cases() -> dict[str, list[str]]:
    """Each case's command-line arguments (after ``vision-cal``), ``OUT`` its output folder."""
    return {
        "demo": [str(DEMO), "--jobs", "1", "--out", "OUT", "-q"],
        "paper": [str(ROOT / "fixtures" / "paper_sm5"), "--method", "paper", "--out", "OUT",
                  "-q"],
        "paper_lsq": [str(ROOT / "fixtures" / "paper_sm5"), "--out", "OUT", "-q"],
        "tracker": ["calibrate", str(TRACKER / "marks.csv"), "--robot",
                    str(TRACKER / "robot.yaml"), "--sigma-mm", "0.02", "--out", "OUT", "-q"],
    }


def render_demo() -> None:
    """The demo's photos, rendered once (as bench/measure.py --whole)."""
    if (DEMO / "session.json").exists():
        return
    sys.path.insert(0, str(ROOT))
    from vision_cal.estimate.paper import pilot_params
    from vision_cal.world.dataset import render_dataset
    from vision_cal.world.scene import load_scene

    render_dataset(load_scene(ROOT / "renders" / "default.yaml"), DEMO, progress=True,
                   pilot=pilot_params, jobs=None)


def run_cases(dest: Path, code: Path) -> None:
    """Every case run with ``code``'s vision_cal; its JSON files kept under ``dest/<case>``,
    with the output folder's path written as ``<OUT>``."""
    env = dict(os.environ, PYTHONPATH=str(code), OMP_NUM_THREADS="1",
               OPENBLAS_NUM_THREADS="1")
    for name, argv in cases().items():
        with tempfile.TemporaryDirectory(prefix=f"outputs-{name}-") as tmp:
            out = Path(tmp) / "out"
            cmd = [sys.executable, "-m", "vision_cal.commands.main",
                   *[str(out) if a == "OUT" else a for a in argv]]
            r = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=tmp)
            if r.returncode not in (0, 1):      # 1: a verdict that is not "ready"
                raise SystemExit(f"{name}: exit {r.returncode}\n{r.stderr[-2000:]}")
            (dest / name).mkdir(parents=True, exist_ok=True)
            for f in FILES:
                if (out / f).exists():
                    text = (out / f).read_text().replace(str(out), "<OUT>")
                    (dest / name / f).write_text(text)
        print(f"{name}: {', '.join(p.name for p in sorted((dest / name).iterdir()))}",
              flush=True)


def differences(a, b, path: str = "") -> list[tuple[str, object, object]]:
    """Every JSON path where ``a`` and ``b`` differ (values compared exactly; NaN equals NaN)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in list(a) + [k for k in b if k not in a]:
            if k not in a or k not in b:
                out.append((f"{path}/{k}", a.get(k, "<absent>"), b.get(k, "<absent>")))
            else:
                out += differences(a[k], b[k], f"{path}/{k}")
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [(f"{path}[len]", len(a), len(b))]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in differences(x, y, f"{path}[{i}]")]
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return []
    return [] if a == b and type(a) is type(b) else [(path, a, b)]


def _rel(a, b) -> str:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        scale = max(abs(a), abs(b))
        return f" (rel {abs(a - b) / scale:.1e})" if scale else ""
    return ""


def compare(saved: Path, code: Path, show: int = 20) -> int:
    with tempfile.TemporaryDirectory(prefix="outputs-now-") as tmp:
        now = Path(tmp)
        run_cases(now, code)
        bad = 0
        for name in cases():
            for f in FILES:
                old, new = saved / name / f, now / name / f
                if not old.exists() and not new.exists():
                    continue
                if old.exists() != new.exists():
                    print(f"{name}/{f}: present {old.exists()} before, {new.exists()} now")
                    bad += 1
                    continue
                diff = differences(json.loads(old.read_text()), json.loads(new.read_text()))
                print(f"{name}/{f}: " + ("identical" if not diff
                                         else f"{len(diff)} values differ"))
                for p, a, b in diff[:show]:
                    print(f"    {p}: {a!r} -> {b!r}{_rel(a, b)}")
                bad += bool(diff)
        return 1 if bad else 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("action", choices=["save", "compare"])
    ap.add_argument("dir", type=Path)
    ap.add_argument("--code", type=Path, default=ROOT,
                    help="the checkout whose vision_cal runs (default: this one)")
    a = ap.parse_args()
    render_demo()
    if a.action == "save":
        if a.dir.exists():
            shutil.rmtree(a.dir)
        run_cases(a.dir, a.code.resolve())
        return 0
    return compare(a.dir, a.code.resolve())


if __name__ == "__main__":
    sys.exit(main())
