"""The calibration action (``vision-cal calibrate``): one or several dataset folders
measured and calibrated (:func:`vision_cal.actions.pipeline.calibrate_dataset`), or one robot
from several placements (:func:`calibrate_placements`, at the end: refuse a placement given
twice, measure each folder, pose the placements to the estimator,
:func:`vision_cal.estimate.placements.calibrate_placed`, and write every file together), with the
optional report and, for several folders, ``summary.json``. Returns what was found,
which prints itself. Several folders take minutes each, so each folder's outcome (and the
notices before its measuring) goes to the ``tell`` callback as it is done, not at the end."""

from __future__ import annotations

import hashlib
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from vision_cal.actions.console import Outcome, error, say, warn
from vision_cal.actions.pipeline import CalibrationRun, calibrate_dataset, measure_marks
from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.dataset.io import atomic_write_json, written_together
from vision_cal.dataset.marks_csv import session_from_marks_csv
from vision_cal.dataset.out_folder import output_names, refuse_input_folder, writing_into
from vision_cal.dataset.photos import list_photos
from vision_cal.dataset.session import load_session
from vision_cal.errors import CalibrationError, VisionCalError
from vision_cal.estimate.placements import calibrate_placed
from vision_cal.estimate.verdict import Verdict
from vision_cal.measure.replicate import measures_the_print
from vision_cal.measure.survey import applicable, find_survey
from vision_cal.report.html import write_report
from vision_cal.report.summary import format_summary


@dataclass(frozen=True)
class CalibrateRequest:
    """What ``vision-cal calibrate`` was asked (the command's arguments, see its ``--help``)."""

    folders: tuple[str, ...]
    out: str | None = None        # default out/<folder name>
    method: str = "lsq"           # one of vision_cal.config.METHODS
    jobs: int | None = None       # photo measurement processes (default: the cores)
    truth: bool = False           # compare with truth.json (synthetic data)
    report: bool = False          # also report.json and report.html
    joint: bool = False           # the folders are placements of one robot
    quiet: bool = False
    robot: str | None = None      # a marks CSV's robot file (issue 32)
    sigma_mm: float | None = None  # a marks CSV's stated accuracy (mm, one std per axis)
    survey: str | None = None     # survey.json (default: a survey.json in the folder)
    bars_mm: tuple[float, float] | None = None   # the printed 100 mm bars as measured (x, y)


@dataclass(frozen=True)
class OutputsNamed:
    """Several folders, two of them sharing a name: where each one's results go (told
    before the first folder is measured)."""

    outputs: tuple[tuple[str, Path], ...]   # (folder as given, its output folder)

    def show(self, quiet: bool = False) -> int:
        if not quiet:
            print("outputs: " + ", ".join(f"{f} -> {out}" for f, out in self.outputs))
        return 0


@dataclass(frozen=True)
class SurveyFound:
    """The sheet as surveyed that a folder is measured against (told before measuring)."""

    path: Path

    def show(self, quiet: bool = False) -> int:
        if not quiet:
            print(f"measuring against the sheet as surveyed: {self.path}")
        return 0


@dataclass(frozen=True)
class SurveyNotApplied:
    """A survey found (or given) that claims no print field (its solve stopped, its field
    is not significant or does not replicate: ``vision_cal.measure.survey.applicable``):
    the folder is measured without it (told before measuring)."""

    path: Path
    status: str
    reason: str

    def show(self, quiet: bool = False) -> int:
        """Said even when quiet (stderr): the survey beside the folder is not used."""
        print(f"not applying the sheet as surveyed ({self.path}): {self.status}: "
              f"{self.reason}", file=sys.stderr)
        return 0


@dataclass(frozen=True)
class FolderCalibrated:
    """One folder calibrated: the run (its calibration.json written) and the report's
    path (``--report``), told as soon as the folder is done."""

    folder: str
    run: CalibrationRun
    report: Path | None = None

    def show(self, quiet: bool = False) -> int:
        """The summary, then the photos skipped and what was inferred (stderr), the report
        and the file written (said even when quiet)."""
        run = self.run
        if not quiet:
            print(format_summary(run.document, reference=run.session.raw.get("reference")))
        for im in run.document.get("images", []):
            if im.get("status") != "ok":
                warn(f"{self.folder}/{im['file']}: skipped: {im.get('reason')}")
        meas = run.measurement
        for note in (meas.inferred_notes if meas is not None else ()):  # no images list
            warn(f"{self.folder}: {note}")
        if self.report is not None:
            print(f"report: {self.report} ({self.report.stat().st_size / 1e6:.1f} MB)")
        print(f"wrote {run.out_path}")
        return 0


@dataclass(frozen=True)
class FolderFailed:
    """One folder of several that could not be calibrated (the others go on)."""

    folder: str
    reason: str

    def show(self, quiet: bool = False) -> int:
        error(f"{self.folder}: {self.reason}")
        return 0


@dataclass(frozen=True)
class CalibrateOutcome:
    """The run's end: for several folders, their rows (summary.json's ``folders``) and
    where summary.json was written; for one, nothing more to say (its outcome was told).
    Exit code 1 when a folder failed."""

    rows: tuple[dict, ...] = ()
    summary: Path | None = None

    @property
    def failures(self) -> int:
        return sum(r["status"] != "ok" for r in self.rows)

    def table(self) -> str:
        """``vision-cal calibrate A/ B/``: one line per folder (summary.json's rows)."""
        def f(x):
            return "-" if x is None else f"{x:.4f}"

        lines = [f"{'folder':<28}{'status':<8}{'marks':>6}{'skipped':>8}{'rms [mm]':>10}"
                 f"{'held-out':>10}  effects"]
        for r in self.rows:
            if r["status"] != "ok":
                lines.append(f"{r['folder'][-28:]:<28}{'failed':<8}  {r['reason']}")
                continue
            lines.append(f"{r['folder'][-28:]:<28}{'ok':<8}{r['marks']:>6}"
                         f"{r['skipped_photos']:>8}{f(r['residual_rms_mm']):>10}"
                         f"{f(r['validation_rms_mm']):>10}  {', '.join(r['effects']) or 'none'}")
        return "\n".join(lines)

    def show(self, quiet: bool = False) -> int:
        if self.summary is not None:   # several folders: the table even when quiet
            print(self.table())
            print(f"wrote {self.summary}")
        return 1 if self.failures else 0


@dataclass(frozen=True)
class JointCalibrated:
    """``--joint``: the robot-frame calibration.json (its placements, effects and
    verdicts) and where it was written."""

    document: dict
    path: Path

    def lines(self) -> list[str]:
        """``vision-cal calibrate --joint``: each placement's sheet pose and residual, the
        effects, each placement's verdict and the robot's."""
        doc = self.document
        lines = [f"{pl['folder']}: sheet at {pl['angle_deg']:.3f} deg, base "
                 f"({pl['base_mm'][0]:.3f}, {pl['base_mm'][1]:.3f}) mm, rms "
                 f"{pl['residual_rms_mm']:.4f} mm" for pl in doc["placements"]]
        lines.append("effects: " + (", ".join(e["name"] + (f"(joint {e['joint']})"
                                                           if "joint" in e else "")
                                              for e in doc["effects"]) or "none"))
        lines += [f"{pl['folder']}: {Verdict.from_json(pl['verdict']).text}"
                  for pl in doc["placements"]]
        return lines + [f"verdict: {Verdict.from_json(doc['verdict']).text}"]

    def show(self, quiet: bool = False) -> int:
        if not quiet:
            say(self.lines())
        print(f"wrote {self.path}")
        return 0


def _ignore(outcome) -> None:
    pass


def calibrate(req: CalibrateRequest,
              tell: Callable[[Outcome], None] = _ignore) -> CalibrateOutcome | JointCalibrated:
    """Calibrate each folder of ``req`` (or one robot from all of them, ``req.joint``).
    Each folder's outcome (:class:`FolderCalibrated`, :class:`FolderFailed`) and the notices
    before it (:class:`OutputsNamed`, :class:`SurveyFound`) go to ``tell`` when they happen;
    returns the run's end."""
    if req.jobs is not None and req.jobs < 1:
        raise VisionCalError(f"must be at least 1, got {req.jobs}", field="--jobs")
    if req.joint:
        return calibrate_joint(req)
    return calibrate_folders(req, tell)


def calibrate_joint(req: CalibrateRequest) -> JointCalibrated:
    """``--joint``: one robot from several placements (actions/calibrate.py), written
    into OUT (robot frame) and OUT/<folder>/ (each placement's sheet frame)."""
    if req.method != "lsq":
        raise VisionCalError("--joint fits by least squares only", field="--method")
    if req.bars_mm is not None:
        raise VisionCalError("--joint reads each sheet's measured_bar_mm (sheet.json "
                             "printed): give the bars there", field="--bars-mm")
    out = Path(req.out or "out")
    names = output_names(req.folders)
    for n in names:   # --out . with the placements in it: their folders are inputs
        refuse_input_folder(out / n, _inputs(req.folders))
    # an earlier run's results (its top file, every placement's) go to previous/ whole
    # first, the placement folders' caches kept (dataset/out_folder.py)
    with writing_into(out, command="calibrate --joint", inputs=_inputs(req.folders),
                      into=names, quiet=req.quiet):
        doc = calibrate_placements(req.folders, out_dir=out, jobs=req.jobs,
                                   progress=not req.quiet, names=names)
    return JointCalibrated(doc, out / "calibration.json")


def calibrate_folders(req: CalibrateRequest, tell: Callable[[Outcome], None]) -> CalibrateOutcome:
    """Each folder (or marks CSV) into its own output folder, one after the other; with
    several, a folder that fails is told and skipped, and summary.json written at the end."""
    several = len(req.folders) > 1
    csvs = [_is_csv(f) for f in req.folders]
    for name, value in (("--robot", req.robot), ("--sigma-mm", req.sigma_mm)):
        if value is not None and not any(csvs):
            raise VisionCalError("applies to a marks CSV only", field=name)
    names = output_names(req.folders, suffixes=(".csv",))   # never two into one folder
    top = Path(req.out or "out")
    outs = [top / n if (req.out and several) else Path(req.out or f"out/{n}") for n in names]
    for out in outs:   # before any is calibrated: --out . with the folders in it
        refuse_input_folder(out, _inputs(req.folders))
    if several and names != [Path(f).resolve().name for f in req.folders]:
        # two folders share a name: say where each one goes
        tell(OutputsNamed(tuple((str(f), o) for f, o in zip(req.folders, outs))))
    if not several:
        tell(calibrate_one(req, req.folders[0], outs[0], tell))
        return CalibrateOutcome()
    # OUT holds one run: an earlier one's summary.json and folders go to previous/ whole
    # (the folders this run writes keep their caches; dataset/out_folder.py)
    with writing_into(top, command="calibrate", inputs=_inputs(req.folders), into=names,
                      quiet=req.quiet):
        rows = []
        for folder, out in zip(req.folders, outs):
            try:
                done = calibrate_one(req, folder, out, tell)
            except VisionCalError as e:
                tell(FolderFailed(str(folder), str(e)))
                rows.append({"folder": str(folder), "status": "failed", "reason": str(e)})
                continue
            rows.append(_row(folder, done.run))
            tell(done)
        summary = atomic_write_json(top / "summary.json", {"folders": rows})
    return CalibrateOutcome(tuple(rows), summary)


def calibrate_one(req: CalibrateRequest, folder: str, out: Path,
                  tell: Callable[[Outcome], None]) -> FolderCalibrated:
    """One dataset folder (or marks CSV) measured, calibrated and written into ``out``
    (with the report, ``--report``)."""
    # OUT holds one run: an earlier run's results go to OUT/previous/ first, so a
    # failed or interrupted run leaves nothing that looks current; OUT is never the
    # dataset folder, and is locked while written (dataset/out_folder.py)
    is_csv = _is_csv(folder)
    source = (session_from_marks_csv(folder, req.robot, sigma_mm=req.sigma_mm)
              if is_csv else folder)
    # #28: as printed; --survey names the file, else survey.json in the dataset folder (a
    # file given as the folder is never taken for a survey: the dataset reader says what
    # it is)
    survey = (None if is_csv else find_survey(req.survey) if req.survey
              else find_survey(folder) if Path(folder).is_dir() else None)
    if req.survey and survey is None:
        raise VisionCalError("not found", file=str(req.survey))
    if survey is not None:   # issue 37: applied only when it claims a field
        claim = applicable(survey)
        if claim.applied:
            tell(SurveyFound(survey))
        else:
            tell(SurveyNotApplied(survey, claim.status, claim.reason))
            if not measures_the_print(claim):
                survey = None
    with writing_into(out, command="calibrate", inputs=[("DIR", folder)], quiet=req.quiet):
        with written_together():   # measurement.json renamed with calibration.json
            run = calibrate_dataset(source, out_dir=out, method=req.method, jobs=req.jobs,
                                    progress=not req.quiet, truth=req.truth, survey=survey,
                                    bars_mm=req.bars_mm)
        report = _write_report(run, out) if req.report else None
    return FolderCalibrated(str(folder), run, report)


def _is_csv(folder) -> bool:
    return str(folder).lower().endswith(".csv")


def _row(folder, run: CalibrationRun) -> dict:
    """summary.json's row of a folder calibrated."""
    d = run.document
    return {"folder": str(folder), "status": "ok", "out": str(run.out_path),
            "marks": len(d["marks"]),
            "skipped_photos": sum(im.get("status") != "ok" for im in d["images"]),
            "effects": [e["name"] + (f"(joint {e['joint']})" if "joint" in e else "")
                        for e in d["effects"]],
            "residual_rms_mm": d["residual_rms_mm"]["final_model"],
            "validation_rms_mm": d["validation_rms_mm"]["final_model"]}


def _write_report(result, out: Path) -> Path:
    try:
        return write_report(result.out_path, out)
    except BaseException:  # Ctrl-C or a failure: both report files or neither
        for n in ("report.json", "report.html"):
            (out / n).unlink(missing_ok=True)
        raise


def _inputs(folders) -> list:
    return [("DIR", f) for f in folders]


def refuse_same_evidence(sessions) -> None:
    """Refuse placements that share a photo (the same content, whatever its name) or whose
    marks are the same measurements: one placement counted twice shrinks every std by
    sqrt 2 and tests nothing (the same photos under two names took L1's std from 0.0043 to
    0.0030 mm)."""
    seen: dict[str, tuple[Path, Path]] = {}     # content hash -> (folder, photo)
    marks_seen: dict[str, Path] = {}
    for s in sessions:
        root = Path(s.root)
        files = ([im.file for im in s.images] if s.images_listed and s.images
                 else list_photos(root) if root.is_dir() else [])
        for f in files:
            p = root / f
            try:
                h = hashlib.sha256(p.read_bytes()).hexdigest()
            except OSError:
                continue        # the measurement says why it cannot read it
            if h in seen and seen[h][0].resolve() != root.resolve():
                raise CalibrationError(f"{p} and {seen[h][1]} are the same photo (same "
                                       "content): each placement is a sheet placed and "
                                       "photographed on its own; give each folder once")
            seen.setdefault(h, (root, p))
        given = [(m.joints_deg, m.measured_mm) for m in s.marks if m.measured_mm is not None]
        if given:
            h = hashlib.sha256(repr(sorted(given)).encode()).hexdigest()
            if h in marks_seen:
                raise CalibrationError(f"{s.path} and {marks_seen[h]} give the same marks "
                                       "(same commands, same measured_mm): one placement "
                                       "given twice; give each folder once")
            marks_seen[h] = s.path


def calibrate_placements(folders, *, out_dir, jobs: int | None = None,
                         progress: bool = False,
                         config: EstimatorConfig | None = None, names=None) -> dict:
    """``vision-cal calibrate A/ B/ C/ --joint --out X``: measure each folder, fit one robot
    and one sheet pose per placement, write ``X/calibration.json`` (robot frame R) and
    ``X/<folder>/calibration.json`` (each placement's sheet frame, for ``plan``).
    Returns the robot-frame document. ``config``: the thresholds (default ``DEFAULT``),
    recorded as its ``config``. ``names``: each placement's sub-folder (default
    :func:`~vision_cal.dataset.out_folder.output_names`: ``d1-plan`` and ``d2-plan`` for two
    folders named ``plan``)."""
    config = config or DEFAULT
    out_dir = Path(out_dir)
    names = list(names) if names is not None else output_names(folders)
    loaded = [load_session(folder) for folder in folders]
    refuse_same_evidence(loaded)
    cals = []
    for session, name in zip(loaded, names):
        _, data, _ = measure_marks(session, out_dir=out_dir / name, jobs=jobs, progress=progress,
                                   config=config)
        cals.append(data.select("calibration"))
    joint, subs = calibrate_placed(names, loaded, cals, config)
    with written_together():   # every placement's file and the top one, or none
        for name, sub in zip(names, subs):
            sub.write(out_dir / name / "calibration.json")
        joint.write(out_dir / "calibration.json")
    return joint.to_json()
