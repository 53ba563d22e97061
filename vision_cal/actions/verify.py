"""The check of a calibration (``vision-cal verify``): the check's photos measured and
compared with calibration.json (:func:`vision_cal.workflows.verify.verify_folder`), written into an
output folder that is never an input's (:func:`vision_cal.dataset.out_folder.writing_into`).
Returns what was found, which prints itself."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from vision_cal.actions.console import say, warn
from vision_cal.dataset.out_folder import writing_into
from vision_cal.errors import VisionCalError
from vision_cal.estimate.verify import VerifyResult
from vision_cal.workflows.verify import verify_folder


@dataclass(frozen=True)
class VerifyRequest:
    """What ``vision-cal verify`` was asked (see its ``--help``)."""

    calibration: str              # CAL.json
    folder: str                   # the check's photos and session.json
    out: str | None = None        # default PHOTOS_verify beside the photos
    force: bool = False           # check marks outside the calibration's valid_for
    jobs: int | None = None       # photo measurement processes (default: every core)
    quiet: bool = False


@dataclass(frozen=True)
class VerifyOutcome:
    """The check's result, where verify.json was written, and the warnings (``--force``:
    marks compared beyond what was calibrated) for the console."""

    result: VerifyResult
    path: Path
    warnings: tuple[str, ...] = ()
    written: tuple[Path, ...] = ()    # every file the check wrote into its folder

    def lines(self) -> list[str]:
        """``vision-cal verify``: each mark's error, the RMS and its bound, which parameters
        moved, ISO 9283 and the verdict with its reasons."""
        r = self.result
        lines = [f"{'mark':<8}{'error x':>10}{'error y':>10}{'|error|':>10}  [mm, the sheet's "
                 "placement taken out]"]
        for mid, m in r.marks.items():
            ex, ey = m["error_mm"]
            lines.append(f"{mid:<8}{ex:>+10.4f}{ey:>+10.4f}{m['error_norm_mm']:>10.4f}")
        lines.append(f"RMS {r.rms_mm['sheet_placed']:.4f} mm (bound for 'still good': "
                     f"{r.bound_mm:.4f} mm)")
        lines.append(f"{'parameter':<12}{'change':>10}{'std':>9}  moved?")
        for label, c in r.changes.items():
            if c.get("sheet_placement"):
                continue
            lines.append(f"{label:<12}{c['delta']:>+10.4f}{c['std']:>9.4f}  "
                         f"{'yes' if c['moved'] else 'no'} ({c['sigmas']:.1f} std)")
        if r.iso9283:
            lines.append("ISO 9283 (each visit's own commanded point taken out; assumes the "
                         "robot's error is the same over each point's few-mm grid of visits):")
            lines += [f"  {name}: AP {v['AP_mm']:.4f} mm, RP {v['RP_mm']:.4f} mm "
                      f"({v['n']} visits)" for name, v in r.iso9283.items()]
        lines.append(f"verdict: {r.verdict}")
        lines += [f"  - {reason}" for reason in r.reasons]   # one finding or action a line
        others = [p.name for p in self.written if p != self.path]
        return lines + [f"wrote {self.path}" + (f" (and {', '.join(others)} beside it: the "
                                                 "photos as measured)" if others else "")]

    def show(self, quiet: bool = False) -> int:
        for w in self.warnings:   # --force: the check compared beyond what was calibrated
            warn(w)
        if not quiet:
            say(self.lines())
        return 0


def default_out(folder) -> Path:
    """Where a check's results go without ``-o``: ``PHOTOS_verify`` beside the photos,
    named as the user named the folder (``check/`` -> ``check_verify``: a relative path
    stays relative, so the console says what the user typed, not the machine's path)."""
    folder = Path(folder)
    if folder.name in ("", ".", ".."):
        here = folder.resolve()
        return here.with_name(here.name + "_verify")
    return folder.parent / f"{folder.name}_verify"


def verify(req: VerifyRequest) -> VerifyOutcome:
    """Check ``req.calibration`` on the photos of ``req.folder``; writes verify.json."""
    if req.jobs is not None and req.jobs < 1:
        raise VisionCalError(f"must be at least 1, got {req.jobs}", field="--jobs")
    folder = Path(req.folder)
    out = Path(req.out) if req.out else default_out(folder)
    # the output folder: never the photos' folder nor the one holding CAL.json; an earlier
    # check's results go to previous/; locked while written (issue 30)
    with writing_into(out, command="verify", field="-o",
                      inputs=[("CAL.json", req.calibration), ("PHOTOS/", req.folder)],
                      quiet=req.quiet) as out:
        r, path, said = verify_folder(req.calibration, folder, out_dir=out, jobs=req.jobs,
                                      progress=not req.quiet, force=req.force)
    written = tuple(sorted(p for p in Path(out).iterdir() if p.is_file()
                           and not p.name.startswith(".")))
    return VerifyOutcome(r, path, tuple(said), written)
