"""Do two versions of vision-cal write the same numbers? Run a list of commands with each
version into its own folder and compare every value of every JSON (and CSV) file the two
wrote, numbers within a relative tolerance.

    # two git refs (each exported with `git archive`, run with its own vision_cal first on
    # the path, this worktree's .venv), the cases in bench/compare_cases.txt:
    python bench/compare_outputs.py --refs main HEAD --work /tmp/cmp

    # one ref only (its outputs kept in /tmp/cmp/main, the shared inputs reused), then two
    # output folders written already (by hand, or by earlier --refs runs):
    python bench/compare_outputs.py --refs main --work /tmp/cmp --reuse-setup
    python bench/compare_outputs.py --dirs /tmp/cmp/main /tmp/cmp/HEAD --rtol 1e-9

    # only some cases, and keep going past a difference:
    python bench/compare_outputs.py --refs main HEAD --work /tmp/cmp --only paper_lsq tracker

The cases file (default ``bench/compare_cases.txt``): one case a line, ``name: command``,
``#`` comments. The command is vision-cal's arguments (``vision-cal`` itself left out), or
``python script.py ...`` / ``python -c ...`` run with that version's package. Placeholders:
``{out}`` is the side's output folder (each case writes under it, e.g. ``{out}/paper``),
``{shared}`` a folder both sides read (inputs made once: a case whose name starts with
``setup`` runs once, with the first side's code, before any other case), ``{tree}`` the
side's source tree (fixtures/ and renders/ of that version) and ``{root}`` this worktree.
Commands run in the side's tree with one thread for BLAS and OpenCV (``OMP_NUM_THREADS=1``,
``OPENCV_FOR_THREADS_NUM=1``: OpenCV's threads sum in another order each run, and a lens
estimated from the photos then moves by 1e-8 to 5e-5 from one run to the next) and ``nice``.

What is compared: every ``*.json`` and ``*.csv`` file under the two folders (paths
relative to them), value by value: numbers equal within ``rtol * max(|a|, |b|) + atol``;
strings equal after the sides' own folder names are replaced by one token, and the
numbers inside a sentence compared as numbers (a sentence printing 0.0123 against 0.0124
is a difference, reported with both sentences); NaN equals NaN; keys (``--ignore``
regexes over the dotted path, e.g. ``dataset.elapsed_s``) skipped. Each case's exit code is
compared too. Printed: one line per difference (file, path, a, b, relative difference),
then a summary per file; exit 1 when anything differs, 0 otherwise.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import re
import shlex
import shutil
import subprocess
import sys
import tarfile
import io
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_CASES = ROOT / "bench" / "compare_cases.txt"
#: keys never compared by default: wall-clock times, the package's version and the paths
#: of the run itself
DEFAULT_IGNORE = (r"(^|\.)elapsed(_s)?$", r"(^|\.)seconds$", r"(^|\.)created(_at)?$",
                  r"(^|\.)version$", r"(^|\.)timings?(\.|$)", r"(^|\.)duration_s$")
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
RUNNER = ("import sys; from vision_cal.commands.main import main; "
          "import vision_cal, os; assert os.path.realpath(vision_cal.__file__).startswith("
          "os.path.realpath(sys.argv[1])), vision_cal.__file__; sys.exit(main(sys.argv[2:]))")


# --------------------------------------------------------------------------- running

def read_cases(path: Path, only: list[str] | None) -> list[tuple[str, str]]:
    cases = []
    for line in path.read_text().splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        name, _, cmd = line.partition(":")
        cases.append((name.strip(), cmd.strip()))
    if only:
        unknown = set(only) - {n for n, _ in cases}
        if unknown:
            sys.exit(f"{path}: no case {sorted(unknown)}")
        cases = [(n, c) for n, c in cases if n in only or n.startswith("setup")]
    return cases


def export_ref(ref: str, dest: Path) -> Path:
    """The tree of git ``ref`` written to ``dest`` (``git archive``; no worktree made)."""
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    data = subprocess.run(["git", "archive", ref], cwd=ROOT, check=True,
                          capture_output=True).stdout
    with tarfile.open(fileobj=io.BytesIO(data)) as tar:
        tar.extractall(dest, filter="data")
    return dest


def run_case(name: str, cmd: str, *, tree: Path, out: Path, shared: Path, log: Path) -> int:
    fill = {"out": str(out), "shared": str(shared), "tree": str(tree), "root": str(ROOT)}
    args = [a.format(**fill) for a in shlex.split(cmd)]
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1",
               OPENBLAS_NUM_THREADS="1", OPENCV_FOR_THREADS_NUM="1", PYTHONHASHSEED="0")
    if args[0] == "python":
        full = [sys.executable, *args[1:]]
    else:
        full = [sys.executable, "-c", RUNNER, str(tree / "vision_cal"), *args]
    t0 = time.perf_counter()
    p = subprocess.run(["nice", "-n", "10", *full], cwd=tree, env=env, capture_output=True,
                       text=True)
    log.mkdir(parents=True, exist_ok=True)
    (log / f"{name}.txt").write_text(
        f"$ {shlex.join(args)}\nexit {p.returncode} after {time.perf_counter() - t0:.1f} s\n"
        f"--- stdout\n{p.stdout}\n--- stderr\n{p.stderr}\n")
    print(f"  {name}: exit {p.returncode} ({time.perf_counter() - t0:.1f} s)", flush=True)
    return p.returncode


def run_side(label: str, tree: Path, out: Path, shared: Path, cases, *, setup: bool) -> dict:
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    print(f"{label}: {tree}", flush=True)
    codes = {}
    for name, cmd in cases:
        if name.startswith("setup") != setup:
            continue
        codes[name] = run_case(name, cmd, tree=tree, out=out, shared=shared,
                               log=out / "_log")
    (out / "_log").mkdir(exist_ok=True)   # a cases file may have no setup case
    (out / "_log" / "exit_codes.json").write_text(json.dumps(codes, indent=1))
    return codes


# --------------------------------------------------------------------------- comparing

class Differences:
    def __init__(self, rtol: float, atol: float, ignore, tokens: list[tuple[str, str]]):
        self.rtol, self.atol = rtol, atol
        self.ignore = [re.compile(p) for p in ignore]
        self.tokens = tokens           # (side a's text, side b's text) -> one token
        self.rows: list[tuple[str, str, object, object, float]] = []
        self.compared = 0

    def _close(self, a: float, b: float) -> tuple[bool, float]:
        if math.isnan(a) and math.isnan(b):
            return True, 0.0
        if math.isinf(a) or math.isinf(b):
            return a == b, (0.0 if a == b else math.inf)
        d = abs(a - b)
        scale = max(abs(a), abs(b))
        return d <= self.rtol * scale + self.atol, (d / scale if scale else d)

    def _text(self, s: str, side: int) -> str:
        for pair in self.tokens:
            s = s.replace(pair[side], "<OUT>")
        return s

    def value(self, file: str, path: str, a, b) -> None:
        if any(p.search(path) for p in self.ignore):
            return
        if isinstance(a, dict) and isinstance(b, dict):
            for k in sorted(set(a) | set(b), key=str):
                p = f"{path}.{k}" if path else str(k)
                if k not in a or k not in b:
                    if not any(r.search(p) for r in self.ignore):
                        self.rows.append((file, p, a.get(k, "<absent>"), b.get(k, "<absent>"),
                                          math.inf))
                    continue
                self.value(file, p, a[k], b[k])
            return
        if isinstance(a, list) and isinstance(b, list):
            if len(a) != len(b):
                self.rows.append((file, path, f"<{len(a)} items>", f"<{len(b)} items>", math.inf))
                return
            for i, (x, y) in enumerate(zip(a, b)):
                self.value(file, f"{path}[{i}]", x, y)
            return
        self.compared += 1
        num = (int, float)
        if isinstance(a, num) and isinstance(b, num) and not isinstance(a, bool) \
                and not isinstance(b, bool):
            ok, rel = self._close(float(a), float(b))
            if not ok:
                self.rows.append((file, path, a, b, rel))
            return
        if isinstance(a, str) and isinstance(b, str):
            sa, sb = self._text(a, 0), self._text(b, 1)
            if sa == sb:
                return
            if NUMBER.sub("#", sa) == NUMBER.sub("#", sb):
                na, nb = NUMBER.findall(sa), NUMBER.findall(sb)
                worst = max(self._close(float(x), float(y))[1] for x, y in zip(na, nb))
                self.rows.append((file, path, a, b, worst))
            else:
                self.rows.append((file, path, a, b, math.inf))
            return
        if a != b:
            self.rows.append((file, path, a, b, math.inf))


def load(path: Path):
    if path.suffix == ".json":
        # Infinity / NaN are read as Python's (json's default), so they compare too
        return json.loads(path.read_text())
    with path.open(newline="") as f:
        rows = list(csv.reader(f))

    def cell(x):
        try:
            return float(x)
        except ValueError:
            return x
    return [[cell(x) for x in r] for r in rows]


def compare_dirs(a: Path, b: Path, diff: Differences) -> list[str]:
    """Every JSON/CSV file of ``a`` and ``b`` compared into ``diff``; returns the files
    found on one side only."""
    files_a = {p.relative_to(a) for p in a.rglob("*") if p.suffix in (".json", ".csv")
               and "_log" not in p.relative_to(a).parts}
    files_b = {p.relative_to(b) for p in b.rglob("*") if p.suffix in (".json", ".csv")
               and "_log" not in p.relative_to(b).parts}
    for rel in sorted(files_a & files_b):
        diff.value(str(rel), "", load(a / rel), load(b / rel))
    return sorted(str(p) for p in files_a ^ files_b)


def short(v, n: int = 70) -> str:
    s = json.dumps(v) if not isinstance(v, str) else v
    return s if len(s) <= n else s[:n - 3] + "..."


def report(diff: Differences, one_sided: list[str], codes: tuple[dict, dict] | None) -> int:
    bad = 0
    if codes is not None:
        for name in sorted(set(codes[0]) | set(codes[1])):
            if codes[0].get(name) != codes[1].get(name):
                print(f"EXIT {name}: {codes[0].get(name)} vs {codes[1].get(name)}")
                bad += 1
    for f in one_sided:
        print(f"ONLY ON ONE SIDE: {f}")
        bad += 1
    per_file: dict[str, int] = {}
    for file, path, x, y, rel in sorted(diff.rows, key=lambda r: (r[0], -r[4], r[1])):
        per_file[file] = per_file.get(file, 0) + 1
        print(f"{file}: {path}: {short(x)} vs {short(y)} (rel {rel:.3g})")
    for file, n in sorted(per_file.items()):
        print(f"  {file}: {n} values differ")
    print(f"{diff.compared} values compared, {len(diff.rows)} differ beyond rtol "
          f"{diff.rtol:g} (atol {diff.atol:g}); {bad} exit codes / files differ")
    return 1 if (diff.rows or bad) else 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--refs", nargs="+", metavar="REF",
                   help="two git refs to run and compare (one: only run it, into WORK/REF)")
    g.add_argument("--dirs", nargs=2, metavar=("A", "B"), help="two output folders to compare")
    ap.add_argument("--work", default="/tmp/compare_outputs",
                    help="where --refs writes trees, shared inputs and outputs")
    ap.add_argument("--cases", default=str(DEFAULT_CASES))
    ap.add_argument("--only", nargs="*", help="case names to run (setup cases always run)")
    ap.add_argument("--rtol", type=float, default=1e-9)
    ap.add_argument("--atol", type=float, default=1e-12,
                    help="absolute tolerance (values that should be zero)")
    ap.add_argument("--ignore", nargs="*", default=list(DEFAULT_IGNORE),
                    help="regexes over the dotted path of values not compared")
    ap.add_argument("--reuse-setup", action="store_true",
                    help="keep the shared inputs of an earlier run (setup cases skipped)")
    args = ap.parse_args(argv)
    if args.refs and len(args.refs) > 2:
        ap.error("--refs takes one or two refs")
    codes = None
    if args.refs:
        work = Path(args.work)
        cases = read_cases(Path(args.cases), args.only)
        shared = work / "shared"
        sides = []
        for i, ref in enumerate(args.refs):
            label = re.sub(r"[^A-Za-z0-9_.-]", "_", ref)
            if label in [s[0] for s in sides]:
                label += f"_{i}"
            tree = export_ref(ref, work / "trees" / label)
            sides.append((label, tree, work / label))
        if not (args.reuse_setup and shared.exists()):
            if shared.exists():
                shutil.rmtree(shared)
            shared.mkdir(parents=True)
            run_side("setup", sides[0][1], work / "setup_out", shared, cases, setup=True)
        codes = tuple(run_side(label, tree, out, shared, cases, setup=False)
                      for label, tree, out in sides)
        if len(sides) == 1:
            print(f"outputs in {sides[0][2]}; compare with --dirs")
            return 0
        a, b = sides[0][2], sides[1][2]
        tokens = [(str(a), str(b)), (str(sides[0][1]), str(sides[1][1]))]
    else:
        a, b = Path(args.dirs[0]), Path(args.dirs[1])
        # folders of --refs runs: their source trees are named in the outputs too
        tokens = [(str(a), str(b)), (str(a.parent / "trees" / a.name),
                                     str(b.parent / "trees" / b.name))]
    diff = Differences(args.rtol, args.atol, args.ignore, tokens)
    one_sided = compare_dirs(a, b, diff)
    return report(diff, one_sided, codes)


if __name__ == "__main__":
    sys.exit(main())
