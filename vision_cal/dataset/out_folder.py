"""An OUT folder holds one run's results, never a mix of two (issue 19).

- :func:`retire_earlier_run`: before a calibration writes anything into OUT, the results
  an earlier run left there (:data:`RESULT_FILES`) are moved into ``OUT/previous/``
  (replacing what an even earlier run left there). So a run that fails, or is stopped with
  Ctrl-C, leaves no calibration.json or report that looks current; the earlier results are
  kept, marked as previous, not lost. The detection cache (``OUT/.cache``) stays: it is
  keyed by the photos' bytes and the settings, never stale.
- :func:`output_names`: one output sub-folder name per dataset folder: the folder's name,
  or, when two folders share a name (``day1/plan day2/plan``), their names with as many
  parent folders as needed to tell them apart (``day1-plan``, ``day2-plan``). The same
  folder given twice is refused.
"""

from __future__ import annotations

import os
from pathlib import Path

from vision_cal.errors import VisionCalError

#: what one calibration run writes into OUT (the cache excepted)
RESULT_FILES = ("calibration.json", "measurement.json", "report.json", "report.html")
PREVIOUS = "previous"


def retire_earlier_run(out_dir) -> list[str]:
    """Move an earlier run's :data:`RESULT_FILES` from ``out_dir`` to ``out_dir/previous/``;
    returns the names moved (none: nothing to do)."""
    out = Path(out_dir)
    found = [n for n in RESULT_FILES if (out / n).is_file()]
    if not found:
        return []
    prev = out / PREVIOUS
    try:
        if prev.exists() and not prev.is_dir():
            raise VisionCalError("is a file, expected a folder for the earlier run's results",
                                 file=str(prev), field="--out")
        prev.mkdir(exist_ok=True)
        for n in RESULT_FILES:  # the even earlier set goes: previous/ holds one run
            (prev / n).unlink(missing_ok=True)
        for n in found:
            os.replace(out / n, prev / n)
    except OSError as e:
        raise VisionCalError(f"cannot move the earlier run's results aside: "
                             f"{e.strerror or e}", file=str(out), field="--out") from e
    return found


def output_names(folders) -> list[str]:
    """One sub-folder name per dataset folder, unique (see the module docstring)."""
    paths = [Path(f).resolve() for f in folders]
    for i, p in enumerate(paths):
        if p in paths[:i]:
            raise VisionCalError(f"given twice (as {folders[paths.index(p)]} and {folders[i]})",
                                 file=str(folders[i]), field="DIR")
    names = []
    for p in paths:
        depth = 1
        while True:
            name = "-".join(p.parts[-depth:]) if depth <= len(p.parts) - 1 else str(p)
            others = ["-".join(q.parts[-depth:]) for q in paths if q != p]
            if name not in others or depth >= len(p.parts):
                break
            depth += 1
        names.append(name.lstrip(os.sep).replace(os.sep, "-") or "root")
    for i, n in enumerate(names):  # "c-plan" the folder and c/plan: still tell them apart
        if n in names[:i]:
            names[i] = f"{n}-{i + 1}"
    return names
