"""A robot's calibrations over time (``vision-cal history``): every calibration.json under a
folder read (:mod:`vision_cal.report.history`), the CSV and the plot written together.
Returns the rows, which print themselves as the table."""

from __future__ import annotations

from dataclasses import dataclass

from vision_cal.actions.console import say
from vision_cal.dataset.io import atomic_write_bytes, atomic_write_text, written_together
from vision_cal.dataset.out_folder import output_file_of_kind, replacing_files
from vision_cal.report.history import (HistoryRow, history_csv, history_png, history_table,
                                       read_history)


@dataclass(frozen=True)
class HistoryRequest:
    """What ``vision-cal history`` was asked (see its ``--help``)."""

    folder: str
    out: str | None = None        # CSV
    plot: str | None = None       # PNG
    quiet: bool = False


@dataclass(frozen=True)
class HistoryOutcome:
    """The calibrations found, by date, and the files written (CSV, PNG; in that order)."""

    rows: tuple[HistoryRow, ...]
    written: tuple[str, ...] = ()

    def show(self, quiet: bool = False) -> int:
        if not quiet:
            print(history_table(list(self.rows)))
            say(f"wrote {p}" for p in self.written)
        return 0


def history(req: HistoryRequest) -> HistoryOutcome:
    """Read the calibrations under ``req.folder``; write the CSV and the plot if asked."""
    # an output on a calibration.json, on another output or on a file of another kind is
    # refused before anything is read or written (issue 30)
    if req.out:
        output_file_of_kind(req.out, "csv", field="-o")
    if req.plot:
        output_file_of_kind(req.plot, "png", field="--plot", outputs=[("-o", req.out)])
    rows = read_history(req.folder)
    csv_text = history_csv(rows)
    png = history_png(rows) if req.plot else None
    if not (req.out or req.plot):
        return HistoryOutcome(tuple(rows))
    with replacing_files([("-o", req.out), ("--plot", req.plot)], command="history",
                         quiet=req.quiet), written_together():
        if req.out:
            atomic_write_text(req.out, csv_text)
        if png is not None:
            atomic_write_bytes(req.plot, png)
    return HistoryOutcome(tuple(rows), tuple(p for p in (req.out, req.plot) if p))
