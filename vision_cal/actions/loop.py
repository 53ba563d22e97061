"""The closed loop on a synthetic scene (``vision-cal loop``): :func:`vision_cal.workflows.loop.run_loop`
in a locked output folder, then the report. Returns what was found, which prints itself."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from vision_cal.actions.console import say
from vision_cal.dataset.out_folder import writing_into
from vision_cal.errors import VisionCalError
from vision_cal.workflows.loop import format_table, run_loop
from vision_cal.report.html import write_report
from vision_cal.report.summary import format_summary


@dataclass(frozen=True)
class LoopRequest:
    """What ``vision-cal loop`` was asked (see its ``--help``)."""

    scene: str                    # SCENE.yaml
    out: str
    jobs: int | None = None       # render and measurement processes (default: every core)
    elbow: int = 1                # elbow of the planned targets
    report: bool = True           # DIR/calibration/report.html
    quiet: bool = False


@dataclass(frozen=True)
class LoopOutcome:
    """loop.json's document, the calibration's document (calibration.json as a dict), the
    output folder and the report written (None: ``--no-report``)."""

    loop: dict
    calibration: dict
    out: Path
    report: Path | None = None

    def lines(self) -> list[str]:
        """``vision-cal loop``: the calibration's summary and the targets' table (Table 3)."""
        return [format_summary(self.calibration), "",
                "absolute error of each target, measured from the photographs (Table 3):",
                format_table(self.loop)]

    def report_line(self) -> str:
        """Where the report is, its size, and where the photos it links are."""
        path, photos = self.report, self.out
        return (f"report: {path.resolve()} ({path.stat().st_size / 1e6:.1f} MB; the photos it "
                f"links are in {photos.resolve()})")

    def show(self, quiet: bool = False) -> int:
        if not quiet:
            say(self.lines())
        if self.report is not None:   # said even when quiet: where to look
            print(self.report_line())
        return 0


def loop(req: LoopRequest) -> LoopOutcome:
    """Run the closed loop of ``req.scene`` into ``req.out`` (and its report)."""
    if req.jobs is not None and req.jobs < 1:
        raise VisionCalError(f"must be at least 1, got {req.jobs}", field="--jobs")
    progress = not req.quiet  # a bar on a terminal, else one line per stage
    # OUT holds one loop: an earlier one's files go to previous/loop/ whole (the caches of
    # its measurements kept), files of anything else are refused; locked while written
    with writing_into(req.out, command="loop", reads=[req.scene], alone=True, displace=False,
                      into=("calibration", "measure_*"), quiet=req.quiet) as out:
        doc, run = run_loop(req.scene, out_dir=out, jobs=req.jobs, progress=progress,
                            elbow=req.elbow)
        report = (write_report(run.out_path, out / "calibration", loop=out / "loop.json")
                  if req.report else None)
    return LoopOutcome(doc, run.document, Path(out), report)
