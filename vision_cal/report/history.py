"""A robot's calibrations over time: every calibration.json under a folder, one table and plot.

Each calibration is dated by its ``report.json`` (``provenance.created_utc``, written with
``--report``) when one sits beside it, else by the file's modification time (said in the
``dated_by`` column: a copied file keeps no date of its own). Rows are in date order; each
parameter is given with its std (1 sigma, calibration.json ``std``), the effects found, the
held-out RMS and the verdict when the file carries one.

Nothing here fits anything: it reads the files (``CalibrationResult.read``) and lays them
out.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from vision_cal.dataset.calibration_result import CalibrationResult, ModelRms
from vision_cal.dataset.io import read_json
from vision_cal.errors import VisionCalError

PARAMS = (("L1_mm", "L1_mm", None), ("L2_mm", "L2_mm", None), ("z1_deg", "joint_zero_deg", 0),
          ("z2_deg", "joint_zero_deg", 1), ("base_x_mm", "base_mm", 0),
          ("base_y_mm", "base_mm", 1))


@dataclass(frozen=True)
class HistoryRow:
    path: Path
    date_utc: str            # "YYYY-MM-DD HH:MM:SS UTC"
    dated_by: str            # "report.json" | "file time"
    values: dict             # label -> (value, std or None)
    effects: str
    heldout_rms_mm: float | None


def _date(cal_path: Path) -> tuple[str, str]:
    rep = cal_path.with_name("report.json")
    if rep.is_file():
        try:
            d = ((read_json(rep).get("provenance") or {}).get("created_utc"))
            if isinstance(d, str) and d:
                return d, "report.json"
        except VisionCalError:
            pass
    t = datetime.fromtimestamp(cal_path.stat().st_mtime, tz=timezone.utc)
    return t.strftime("%Y-%m-%d %H:%M:%S UTC"), "file time"


def _get(d: dict, key: str, k):
    v = (d or {}).get(key)
    if v is None:
        return None
    try:
        return float(v[k]) if k is not None else float(v)
    except (TypeError, ValueError, IndexError, KeyError):
        return None


def read_history(folder) -> list[HistoryRow]:
    """Every ``calibration.json`` under ``folder`` (recursively), oldest first."""
    folder = Path(folder)
    if not folder.is_dir():
        raise VisionCalError("not a folder", file=str(folder))
    rows = []
    for p in sorted(folder.rglob("calibration.json")):
        cal = CalibrationResult.read(p)     # its one reader: the format and fields checked
        date, how = _date(p)
        values = {label: (_get(cal.params, key, k), _get(cal.std, key, k))
                  for label, key, k in PARAMS}
        eff = ", ".join(
            f"{e.get('name')}(joint {e['joint']})" if "joint" in e else str(e.get("name"))
            for e in cal.effects or [] if isinstance(e, dict)) or "none"
        vr = cal.validation_rms_mm
        val = vr.final_model if isinstance(vr, ModelRms) else None
        rows.append(HistoryRow(p, date, how, values, eff,
                               float(val) if isinstance(val, (int, float)) else None))
    if not rows:
        raise VisionCalError("no calibration.json under it", file=str(folder))
    return sorted(rows, key=lambda r: (r.date_utc, str(r.path)))


def history_csv(rows: list[HistoryRow]) -> str:
    head = ["date_utc", "dated_by", "calibration"]
    for label, _, _ in PARAMS:
        head += [label, f"{label}_std"]
    head += ["heldout_rms_mm", "effects"]
    lines = [",".join(head)]
    for r in rows:
        cells = [r.date_utc, r.dated_by, str(r.path)]
        for label, _, _ in PARAMS:
            v, s = r.values[label]
            cells += ["" if v is None else f"{v:.6f}", "" if s is None else f"{s:.6f}"]
        cells += ["" if r.heldout_rms_mm is None else f"{r.heldout_rms_mm:.6f}", r.effects]
        lines.append(",".join('"' + c.replace('"', "'") + '"' if "," in c else c for c in cells))
    return "\n".join(lines) + "\n"


def history_table(rows: list[HistoryRow]) -> str:
    """The console table: one line per calibration, each parameter as value +-std."""
    head = f"{'date (UTC)':<20}" + "".join(f"{label:>22}" for label, _, _ in PARAMS) + \
        f"{'held-out':>10}  effects"
    out = [head, "-" * len(head)]
    for r in rows:
        cells = []
        for label, _, _ in PARAMS:
            v, s = r.values[label]
            cells.append(f"{'-' if v is None else f'{v:.4f}'}"
                         f"{'' if s is None else f' +-{s:.4f}'}")
        rms = "-" if r.heldout_rms_mm is None else f"{r.heldout_rms_mm:.4f}"
        out.append(f"{r.date_utc[:19]:<20}" + "".join(f"{c:>22}" for c in cells)
                   + f"{rms:>10}  {r.effects}" + ("" if r.dated_by == "report.json"
                                                    else " (dated by file time)"))
    return "\n".join(out)


def history_png(rows: list[HistoryRow]) -> bytes:
    """Each parameter against the calibration's date, with +-1 std error bars (PNG)."""
    import matplotlib   # local: matplotlib is slow to import and only figures need it

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dates = [datetime.strptime(r.date_utc[:19], "%Y-%m-%d %H:%M:%S") for r in rows]
    fig, axes = plt.subplots(3, 2, figsize=(10, 7.5), layout="constrained", sharex=True)
    for ax, (label, _, _) in zip(axes.ravel(), PARAMS):
        v = np.array([np.nan if r.values[label][0] is None else r.values[label][0] for r in rows])
        s = np.array([np.nan if r.values[label][1] is None else r.values[label][1] for r in rows])
        ax.errorbar(dates, v, yerr=np.where(np.isfinite(s), s, 0.0), fmt="o-", ms=4, capsize=3)
        ax.set_ylabel(label.replace("_mm", " [mm]").replace("_deg", " [deg]"))
        ax.grid(alpha=0.3)
        ax.ticklabel_format(axis="y", useOffset=False)
    for ax in axes[-1]:
        ax.tick_params(axis="x", rotation=30)
    fig.suptitle(f"{len(rows)} calibrations: each parameter +- 1 std by date")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    return buf.getvalue()
