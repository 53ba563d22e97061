"""What the README's two commands cost (issue 41): ``make demo`` from a fresh clone (the
``.venv`` created, pip's download cache as the machine has it) and then ``make test`` in
that clone, wall and CPU time each (the CPU of every process they start), with the load
average before and after (the goals, 3 and 5 minutes, are for 2 idle cores: a figure taken
under load is an upper bound, and says so).

``--write``: the figures go to ``docs/speed.json`` (``setup``), a row of the table in
``docs/measured.md`` (between the ``setup_times`` markers) and the README's sentence on
what the demo costs (``tests/test_readme_speed.py`` checks the README against the file).

Usage::

    .venv/bin/python bench/setup_times.py [--only demo|test] [--write] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SPEED_JSON = ROOT / "docs" / "speed.json"
MEASURED = ROOT / "docs" / "measured.md"
README = ROOT / "README.md"
GOALS_S = {"demo": 180.0, "test": 300.0}
BEGIN, END = "<!-- bench/setup_times.py: begin -->", "<!-- bench/setup_times.py: end -->"


def clock(seconds: float) -> str:
    m, s = divmod(int(round(seconds)), 60)
    return f"{m} min {s:02d} s" if m else f"{s} s"


def timed_make(target: str, cwd: Path, log: Path) -> dict:
    """``make TARGET`` in ``cwd``: wall and CPU seconds (children's user + system), exit
    code, load average before and after; its output in ``log``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    load0 = os.getloadavg()[0]
    t = time.perf_counter()
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
    with log.open("w") as f:
        rc = subprocess.run(["make", target], cwd=cwd, stdout=f, stderr=subprocess.STDOUT,
                            env=env).returncode
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    lines = log.read_text().strip().splitlines()
    # the test run's summary ("N failed, M passed ... in S s") when there is one
    tail = [ln for ln in lines if " passed" in ln or " failed" in ln][-1:] or lines[-1:] or [""]
    return {"wall_s": round(wall, 1), "cpu_s": round(cpu, 1), "exit": rc,
            "load_before": round(load0, 1), "load_after": round(os.getloadavg()[0], 1),
            "last_line": tail[0][:200]}


def demo_sentence(demo: dict) -> str:
    """The README's sentence on what ``make demo`` costs, from the figures."""
    idle = demo["load_before"] < 1.0 and demo["load_after"] < 2.0
    lo, hi = sorted((demo["load_before"], demo["load_after"]))
    load = f"{lo:.1f}" if round(lo, 1) == round(hi, 1) else f"{lo:.1f}-{hi:.1f}"
    where = ("on 2 idle cores" if idle else
             f"on {os.cpu_count()} cores shared at load {load} (an upper bound)")
    return (f"It takes {clock(demo['wall_s'])} {where}, creating `.venv` included (pip's "
            f"download cache filled; `docs/speed.json`, `bench/setup_times.py`).")


def measured_row(res: dict) -> str:
    cells = []
    for name, cmd in (("demo", "fresh clone `make demo`"), ("test", "`make test`")):
        if name in res:
            r = res[name]
            said = f": {r['last_line'].strip(' =')}" if name == "test" else ""
            cells.append(f"{cmd} {clock(r['wall_s'])} wall, {clock(r['cpu_s'])} CPU, load "
                         f"{r['load_before']:.1f} -> {r['load_after']:.1f}, exit {r['exit']}"
                         f"{said} (goal {clock(GOALS_S[name])} on 2 idle cores)")
    return (f"| the README's two commands ({res['measured']}, {res['commit']}) | "
            + "; ".join(cells) + " | `bench/setup_times.py` |")


def write(res: dict) -> None:
    old = json.loads(SPEED_JSON.read_text()) if SPEED_JSON.exists() else {}
    setup = dict(old.get("setup", {}), **res)
    if "demo" in setup:
        setup["readme_demo"] = demo_sentence(setup["demo"])
    old["setup"] = setup
    SPEED_JSON.write_text(json.dumps(old, indent=1) + "\n")
    text = MEASURED.read_text()
    block = f"{BEGIN}\n{measured_row(setup)}\n{END}"
    if BEGIN in text:
        text = re.sub(re.escape(BEGIN) + ".*?" + re.escape(END), lambda _: block, text,
                      flags=re.S)
    else:
        text = text.rstrip("\n") + "\n" + block + "\n"
    MEASURED.write_text(text)
    if "readme_demo" in setup:
        readme = README.read_text()
        new = re.sub(r"It takes [^.]*?\s(?:on\s+2\s+idle\s+cores|cores\s+shared\s+at\s+load"
                     r"[^,]*?),\s+creating\s+`\.venv`\s+included\s+\(pip's\s+download\s+cache"
                     r"\s+filled[^)]*\)\.", lambda _: setup["readme_demo"], readme, count=1)
        README.write_text(new)
        print("README: " + ("updated" if new != readme else "sentence not found or unchanged"))
    print(f"wrote {SPEED_JSON.relative_to(ROOT)}, {MEASURED.relative_to(ROOT)}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=["demo", "test"])
    ap.add_argument("--write", action="store_true")
    ap.add_argument("--keep", type=Path, help="clone here and keep it (default: a temp dir)")
    a = ap.parse_args()
    base = a.keep or Path(tempfile.mkdtemp(prefix="vision-cal-setup-"))
    clone = base / "vision-cal"
    if clone.exists():
        shutil.rmtree(clone)
    subprocess.run(["git", "clone", "--quiet", "--no-hardlinks", str(ROOT), str(clone)],
                   check=True)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=clone, check=True,
                            capture_output=True, text=True).stdout.strip()
    print(f"fresh clone of {commit} in {clone}; load average {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} cores", flush=True)
    res = {"measured": date.today().isoformat(), "commit": commit}
    try:
        for target in ("demo", "test"):
            if target == "test" and "demo" not in res and a.only != "test":
                break
            if a.only and a.only != target:
                continue
            r = timed_make(target, clone, base / f"make_{target}.log")
            res[target] = r
            ok = r["exit"] == 0 and r["wall_s"] <= GOALS_S[target]
            print(f"make {target}: {clock(r['wall_s'])} wall, {clock(r['cpu_s'])} CPU, exit "
                  f"{r['exit']}, load {r['load_before']:.1f} -> {r['load_after']:.1f} (goal "
                  f"{clock(GOALS_S[target])} on 2 idle cores: {'met' if ok else 'not met'}"
                  f"{'' if r['load_before'] < 1.0 else ', under load'}); {r['last_line']}",
                  flush=True)
    finally:
        if not a.keep:
            shutil.rmtree(base, ignore_errors=True)
    if a.write:
        write(res)
    return 0


if __name__ == "__main__":
    sys.exit(main())
