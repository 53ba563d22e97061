"""The robot's part rehearsed (``vision-cal simulate``): a simulated robot draws a plan and
photographs it (:func:`vision_cal.world.rehearse.simulate_session`), the photos, session.json
and truth.json renamed into place together. Returns what was drawn, which prints itself
(the world's :class:`~vision_cal.world.rehearse.SimulateResult` wrapped: the world knows
nothing of the console)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from vision_cal.dataset.io import written_together
from vision_cal.dataset.out_folder import writing_into
from vision_cal.dataset.photos import list_photos
from vision_cal.errors import VisionCalError
from vision_cal.world.rehearse import SimulateResult, simulate_session


@dataclass(frozen=True)
class SimulateRequest:
    """What ``vision-cal simulate`` was asked (see its ``--help``)."""

    plan: str                      # PLAN_DIR, or a targets program PLAN.prg
    truth: str                     # TRUE_ROBOT.yaml
    out: str                       # PHOTOS/
    sheet: str | None = None       # targets program: the sheet.json it is drawn on
    targets: str | None = None     # targets program: targets.csv
    after: tuple[str, ...] = ()    # folders simulated before on the same sheet
    seed: int | None = None        # overrides the robot file's seed
    photos: int | None = None      # overrides the simulated camera's number of photos
    quiet: bool = False


@dataclass(frozen=True)
class SimulateOutcome:
    """What the simulated robot drew and photographed (the world's result)."""

    result: SimulateResult

    def line(self) -> str:
        """``vision-cal simulate``: the marks drawn (off the paper, on a printed marker) and
        the photos taken."""
        r = self.result
        n = len(r.photos)
        photos = f"{n} photo{'s' if n != 1 else ''}"
        if r.blank:
            return (f"the blank sheet photographed from {n} place{'s' if n != 1 else ''} -> "
                    f"{r.out_dir}/ (truth.json: the markers as printed)")
        if r.n_poses:   # a camera on the arm: no pen
            return (f"the simulated arm camera took {photos} at {r.n_poses} "
                    f"pose{'s' if r.n_poses != 1 else ''} -> {r.out_dir}/ (truth.json: "
                    "the camera's mount, T_flange_camera)")
        extra = []
        if r.off_paper:
            extra.append(f"{len(r.off_paper)} off the paper")
        if r.on_marker:
            extra.append(f"{len(r.on_marker)} on a printed marker")
        return (f"the simulated robot drew {r.n_marks} marks"
                + (f" ({', '.join(extra)})" if extra else "")
                + f"; {photos} -> {r.out_dir}/ (truth.json: where they really "
                  "are)")

    def show(self, quiet: bool = False) -> int:
        if not quiet:
            print(self.line())
        return 0


def simulate(req: SimulateRequest) -> SimulateOutcome:
    """Draw and photograph ``req.plan`` with the simulated robot of ``req.truth``."""
    if req.seed is not None and req.seed < 0:
        raise VisionCalError(f"expected a non-negative integer, got {req.seed}", field="--seed")
    # locked while written; an earlier rehearsal's photos, session.json and truth.json go
    # to previous/simulate/ whole (photos of anything else are refused), and this one's are
    # renamed into place together at the end, so an interrupted run leaves none of them
    into_plan = Path(req.plan).is_dir() and Path(req.plan).resolve() == Path(req.out).resolve()
    with writing_into(req.out, command="simulate",
                      reads=[req.plan, req.truth, req.sheet, req.targets, *req.after],
                      writes=("truth.json",) if into_plan else ("truth.json", "session.json"),
                      refuse=_no_other_photos, quiet=req.quiet), written_together():
        return SimulateOutcome(simulate_session(
            req.plan, req.truth, req.out, after=list(req.after), progress=not req.quiet,
            rng=req.seed, sheet_json=req.sheet, targets=req.targets, photos=req.photos))


def _no_other_photos(out: Path, moving) -> None:
    """Photos in OUT that no earlier rehearsal took there (the user's, a render's) are
    refused before anything moves: a rehearsal adds its own."""
    photos = [p for p in list_photos(out) if p not in moving]
    if photos:
        raise VisionCalError(f"holds photos already ({photos[0]}, ...) that no earlier "
                             "`vision-cal simulate` took: a rehearsal adds its own; choose an "
                             "empty folder", file=str(out), field="--out")
