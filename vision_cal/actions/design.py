"""The action of ``vision-cal design``: what the robot must draw (the pilot, then the
informative plan)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from vision_cal.actions.console import say, warn

from vision_cal.estimate.plausible import check_links_against
from vision_cal.camera.arm_design import check_design, design_camera_on_arm
from vision_cal.dataset.calibration import refuse_robot_frame
from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.dataset.io import written_together
from vision_cal.dataset.out_folder import writing_into
from vision_cal.dataset.photos import list_photos
from vision_cal.dataset.robot import load_robot_file
from vision_cal.dataset.session import load_sheet_file, sheet_file_block
from vision_cal.dataset.trust import require_usable_pilot
from vision_cal.design.placements import design_placements
from vision_cal.design.stage import DesignResult, design_stage
from vision_cal.errors import VisionCalError
from vision_cal.measure.replicate import measures_the_print
from vision_cal.measure.survey import applicable, copy_survey, find_survey, load_survey


@dataclass(frozen=True)
class DesignRequest:
    """What ``vision-cal design`` was asked (its arguments; see ``vision-cal design --help``)."""

    robot: str
    sheet: str
    out: str
    quiet: bool = False
    pilot: str | None = None
    verify: str | None = None
    iso9283: int = 0
    program: str = 'spel'
    n_calibration: int = 30
    n_validation: int = 8
    safety_mm: float | None = None
    seed: int = 0
    placements: int | None = None
    camera_on_arm: bool = False
    n_poses: int = 24
    mount: str = 'flange'
    trigger: str = 'output'
    trigger_output: int = 8
    repeats: int = 6
    survey: str | None = None     # survey.json (#28; default: one beside --sheet)


@dataclass(frozen=True)
class StageDesigned:
    """A stage's plan (pilot, informative, verify) as designed, and the survey copied beside
    it (None: no survey)."""

    result: DesignResult
    survey: Path | None = None        # the sheet as surveyed that was found
    survey_copy: Path | None = None   # its copy beside the plan
    verify: str | None = None         # the calibration a check plan checks
    out: str = ""
    pilot_note: tuple[str, ...] = ()  # a "check" pilot: what the plan fixes, what is left
    survey_not_applied: str | None = None   # why the survey found is not applied (#37)

    def lines(self) -> list[str]:
        """``vision-cal design``: the survey that goes with the plan, the plan's size and
        what it is for, the files written."""
        r = self.result
        lines = list(self.pilot_note)
        if self.survey_copy is not None:
            lines.append(f"the sheet as surveyed ({self.survey}) goes with the plan: "
                         f"{self.survey_copy}")
        if self.survey_not_applied:   # issue 37: a survey that claims no print field
            lines.append(f"not applying the sheet as surveyed ({self.survey}): "
                         f"{self.survey_not_applied}")
        lines.append(f"{r.stage} plan: {r.n_marks} marks, {r.duration_s:.1f} s of motion")
        if r.stage == "pilot":
            lines.append(f"every mark stays {r.info['worst_case_clearance_mm']:.1f} mm clear "
                         f"of markers and edges for {r.info['placements_checked']} placements "
                         "within the robot file's placement_tolerance")
        elif r.stage == "verify":
            lines.append(f"a check of {self.verify}: draw it on a fresh sheet, photograph it "
                         f"into {self.out}, then: vision-cal verify {self.verify} {self.out}")
        else:
            lines.append(f"placed with the pilot's model, {r.info['safety_mm']:.1f} mm of "
                         "safety")
            beyond = r.info.get("beyond_valid_for") or []
            if beyond:   # by design: the informative plan identifies what the pilot could not
                lines.append("the pilot's model is this plan's starting model (not the "
                             "nominal: that stays the robot file); the plan goes beyond what "
                             "the pilot saw, by design (" + ", ".join(b["field"] for b in beyond)
                             + "): its calibration identifies them (session.json "
                             "design.beyond_valid_for)")
        return lines + [f"wrote {p}" for p in (r.session_path, r.trajectory_path,
                                                r.program_path) if p is not None]

    def show(self, quiet: bool = False) -> int:
        for w in self.result.info.get("warnings", []):
            warn(w)
        if not quiet:
            say(self.lines())
        return 0


@dataclass(frozen=True)
class PlacementsDesigned:
    """Several placements' pilots: each folder with its instruction."""

    placements: tuple[dict, ...]

    def show(self, quiet: bool = False) -> int:
        if not quiet:
            say(f"{p['folder']}: {p['instruction']}" for p in self.placements)
        return 0


@dataclass(frozen=True)
class CameraPosesDesigned:
    """A camera on the arm's poses: session.json and the program written."""

    n_poses: int
    repeats: int
    mount: str
    session: Path
    program: Path
    out: Path

    def lines(self) -> list[str]:
        """``vision-cal design --camera-on-arm``: the poses, where the photos go, what next."""
        return [f"camera poses: {self.n_poses}, {self.repeats} of them taken twice (the "
                f"robot's repeatability, measured) ({self.mount} mount); put the photos beside "
                f"{self.session} (and your camera's lens in it if you know it: camera: "
                f"size_px, K, dist), then vision-cal handeye {self.out} --out CAL/",
                f"wrote {self.session}", f"wrote {self.program}"]

    def show(self, quiet: bool = False) -> int:
        if not quiet:
            say(self.lines())
        return 0


def design(req: DesignRequest) -> StageDesigned | PlacementsDesigned | CameraPosesDesigned:
    """The plan of a calibration stage (pilot, informative, verify), several placements, or
    the camera poses of a camera on the arm."""
    _refuse_conflicts(req)
    if req.seed < 0:
        raise VisionCalError(f"expected a non-negative integer, got {req.seed}", field="--seed")
    if req.iso9283 and req.verify is None:
        raise VisionCalError("ISO 9283's cycles are part of a check: give --verify CAL.json "
                             "with it", field="--iso9283")
    if req.camera_on_arm:
        return _camera_on_arm(req)

    if req.n_calibration < 3 or req.n_validation < 0:
        raise VisionCalError(f"expected at least 3 calibration and 0 validation marks, got "
                             f"{req.n_calibration} and {req.n_validation}",
                             field="--n-calibration")
    if req.safety_mm is not None and not req.safety_mm >= 0:
        raise VisionCalError(f"expected a non-negative number, got {req.safety_mm}",
                             field="--safety-mm")
    if req.placements is not None:   # several placements (design/placements.py, #21)

        if req.pilot:
            raise VisionCalError("--placements designs each placement's pilot; design the "
                                 "informative plans per placement folder", field="--pilot")
        with writing_into(req.out, command="design", reads=_reads(req), refuse=_no_photos,
                          quiet=req.quiet):
            places = design_placements(req.robot, req.sheet, req.out, req.placements,
                                       program=None if req.program == "none" else req.program,
                                       seed=req.seed)
        return PlacementsDesigned(tuple(places))
    if req.verify is not None and req.pilot is not None:
        raise VisionCalError("give either --pilot (the informative plan) or --verify (a check "
                             "of a calibration), not both", field="--verify")
    given = req.pilot if req.pilot is not None else req.verify
    pilot_note: tuple[str, ...] = ()
    if given is not None:
        # read as every reader of calibration.json reads it (the planner's strict reader,
        # load_calibration, follows in design_stage)
        cal = CalibrationResult.read(given)
        refuse_robot_frame(cal, given)
        check_links_against(cal, load_robot_file(req.robot).nominal, file=given,
                            robot_file=req.robot)
        if req.pilot:
            pilot_note = require_usable_pilot(cal, req.pilot)
    # #28: measured against it; found beside the sheet (the sheet file is never the survey)
    survey = find_survey(req.survey) if req.survey else find_survey(Path(req.sheet).parent)
    if req.survey and survey is None:
        raise VisionCalError("not found", file=str(req.survey))
    not_applied, goes_along = None, False
    if survey is not None:   # checked against the sheet before anything is written
        load_survey(survey, load_sheet_file(req.sheet))
        claim = applicable(survey)   # issue 37: not applied when it claims no field
        if not claim.applied:
            not_applied = f"{claim.status}: {claim.reason}"
        # one that found the print on its layout goes with the plan too: it measured it
        goes_along = measures_the_print(claim)
    check = req.verify is not None
    if not 0 <= req.iso9283 <= 30:
        raise VisionCalError(f"expected 1..30 cycles, got {req.iso9283}", field="--iso9283")
    # the earlier design's files (session.json, its program, trajectory, preview, survey
    # copy) go to previous/ whole (dataset/out_folder.py); locked while written
    with writing_into(req.out, command="design", reads=_reads(req), refuse=_no_photos,
                      quiet=req.quiet):
        r = design_stage(req.robot, req.sheet, req.out,
                         pilot=req.verify if check else req.pilot,
                         program=None if req.program == "none" else req.program,
                         n_calibration=10 if check else req.n_calibration,
                         n_validation=0 if check else req.n_validation,
                         safety_mm=req.safety_mm, seed=req.seed,
                         stage="verify" if check else None,
                         iso9283_cycles=req.iso9283 if check else 0)
        dest = (copy_survey(survey, load_sheet_file(req.sheet), r.session_path.parent)
                if survey is not None and goes_along else None)
    return StageDesigned(r, survey, dest, req.verify, req.out, pilot_note, not_applied)


def _reads(req: DesignRequest) -> list:
    """The files a design reads (never moved aside, even in its folder)."""
    return [req.robot, req.sheet, req.pilot, req.verify, req.survey]


def _no_photos(out: Path, moving) -> None:
    """A folder holding photos (of an earlier plan, drawn and photographed) is refused: a
    new design would not match them."""
    photos = [p for p in list_photos(out) if p not in moving]
    if photos:
        raise VisionCalError(f"holds photos ({photos[0]}, ...) of an earlier design: a new "
                             "design would not match them; choose another --out",
                             file=str(out), field="--out")


#: options that contradict each other: (a, b, why); ``a`` and ``b`` name an option given
#: (a request field whose value differs from its default, or ``--program csv``)
_CONFLICTS = (
    ("--verify", "--camera-on-arm", "a check of a pen calibration draws marks, the camera on "
     "the arm photographs a marker field"),
    ("--verify", "--placements", "a check verifies one calibration on one sheet, placements "
     "design a joint calibration"),
    ("--pilot", "--camera-on-arm", "the camera on the arm plans its poses without a pilot"),
    ("--camera-on-arm", "--program csv", "the camera poses are written as a SPEL+ program "
     "with its camera trigger only"),
    ("--camera-on-arm", "--program none", "the camera poses are written as a SPEL+ program "
     "with its camera trigger only"),
)


def _given(req: DesignRequest) -> set[str]:
    """The options of ``_CONFLICTS`` the user gave."""
    given = set()
    if req.verify is not None:
        given.add("--verify")
    if req.pilot is not None:
        given.add("--pilot")
    if req.placements is not None:
        given.add("--placements")
    if req.camera_on_arm:
        given.add("--camera-on-arm")
    if req.program != "spel":
        given.add(f"--program {req.program}")
    return given


def _refuse_conflicts(req: DesignRequest) -> None:
    """Options that contradict each other are refused, naming both (never one silently
    ignored)."""
    given = _given(req)
    for a, b, why in _CONFLICTS:
        if a in given and b in given:
            raise VisionCalError(f"{a} and {b} contradict each other ({why}): give one",
                                 field=a)


def _camera_on_arm(req: DesignRequest) -> CameraPosesDesigned:
    check_design(n_poses=req.n_poses, trigger=req.trigger, seed=req.seed,
                 output_bit=req.trigger_output)
    if not 0 <= req.repeats <= req.n_poses:
        raise VisionCalError(f"expected 0..{req.n_poses} (--n-poses), got {req.repeats}",
                             field="--repeats")
    robot = load_robot_file(req.robot)
    sheet = load_sheet_file(req.sheet)
    with writing_into(req.out, command="design", reads=_reads(req), refuse=_no_photos,
                      quiet=req.quiet) as out:
        with written_together():   # session.json and program.prg both, or neither
            a, b = design_camera_on_arm(robot, sheet, sheet_file_block(req.sheet)[0], out,
                                        n_poses=req.n_poses, mount=req.mount,
                                        trigger=req.trigger, output_bit=req.trigger_output,
                                        seed=req.seed, repeats=req.repeats,
                                        progress=not req.quiet)
    return CameraPosesDesigned(req.n_poses, req.repeats, req.mount, a, b, out)
