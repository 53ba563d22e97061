"""The console, in one place: what each action returned, printed as the command's lines
(stdout; warnings on stderr). ``show(outcome, quiet=...)`` picks the printer by the
outcome's type and returns the command's exit code. The actions write files and return
typed outcomes; they print nothing of their results (progress bars and the output folder's
notices aside). A long action tells each step's outcome as it happens to a callback the
command points at :func:`show` (``calibrate``: each folder, as soon as it is done)."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:   # the outcomes' modules pull numpy, OpenCV and the renderer
    from vision_cal.actions.arm_camera import ArmCameraOutcome
    from vision_cal.actions.calibrate import (CalibrateOutcome, FolderCalibrated, FolderFailed,
                                              JointCalibrated, OutputsNamed, SurveyFound,
                                              SurveyNotApplied)
    from vision_cal.actions.design import CameraPosesDesigned, PlacementsDesigned, StageDesigned
    from vision_cal.actions.export import ExportOutcome
    from vision_cal.actions.handeye import HandeyePairsOutcome, HandeyePhotosOutcome
    from vision_cal.actions.history import HistoryOutcome
    from vision_cal.actions.init import InitOutcome
    from vision_cal.actions.locate import LocateOutcome
    from vision_cal.actions.plan import PlanOutcome
    from vision_cal.actions.loop import LoopOutcome
    from vision_cal.actions.render import RenderOutcome
    from vision_cal.actions.robot_template import RobotTemplateOutcome
    from vision_cal.actions.sheet import SheetOutcome
    from vision_cal.actions.survey import SurveyOutcome
    from vision_cal.actions.verify import VerifyOutcome
    from vision_cal.world.rehearse import SimulateResult


def show(outcome, *, quiet: bool = False) -> int:
    """Print ``outcome`` (nothing but warnings and what a quiet run still says, when
    ``quiet``); the exit code (0 unless the printer says otherwise). The printer is looked up by the outcome's class name, so that
    this module imports none of the actions (a light command stays light)."""
    kind = type(outcome)
    printer = PRINTERS.get(f"{kind.__module__}.{kind.__qualname__}")
    if printer is None:
        raise TypeError(f"no printer for {kind.__module__}.{kind.__qualname__}")
    code = printer(outcome, quiet)
    return code or 0


def arm_camera_lines(o: ArmCameraOutcome) -> list[str]:
    """``vision-cal handeye FOLDER``: the photos used, the arm, the camera's mount, the
    effects and the verdict."""
    # the action that returned ``o`` imported it already
    from vision_cal.estimate.verdict import Verdict

    doc = o.calibration
    cam = doc["cameras"][0]
    p, sd = doc["params"], doc["std"]
    skipped = [im for im in doc["images"] if im["status"] != "ok"]
    lines = [f"{len(cam['images'])} photos used, {len(skipped)} skipped; corner RMS "
             f"{cam['corner_rms_px']:.3f} px",
             f"L1 {p['L1_mm']:.4f} +- {sd['L1_mm']:.4f} mm, L2 {p['L2_mm']:.4f} +- "
             f"{sd['L2_mm']:.4f} mm, zeros {p['joint_zero_deg'][0]:.4f} "
             f"{p['joint_zero_deg'][1]:.4f} deg, base {p['base_mm'][0]:.3f} "
             f"{p['base_mm'][1]:.3f} mm",
             flange_camera_line(cam)]
    lines += [f"joint {e['joint']} backlash {e['deg']:.4f} +- {e['std']:.4f} deg"
              for e in doc["effects"]]
    v = Verdict.from_json(doc["verdict"])
    if v.floor_line:
        lines.append(v.floor_line)
    return lines + _verdict_lines(v) + [f"wrote {o.path}"]


def _verdict_lines(v) -> list[str]:
    """A :class:`~vision_cal.estimate.verdict.Verdict` as the console's lines (one reason a
    line: :func:`vision_cal.report.summary.verdict_lines`)."""
    from vision_cal.report.summary import verdict_lines

    return verdict_lines({**v.to_json(), "text": v.text})


def handeye_pairs_lines(o: HandeyePairsOutcome) -> list[str]:
    """``vision-cal handeye --poses``: the pairs, the camera's pose with its std, the pairs
    left out, and the verdict."""
    # the action that returned ``o`` imported it already
    from vision_cal.estimate.verdict import Verdict

    fit, xname = o.fit, o.camera_name
    t, sd = fit.X[:3, 3], o.document["cameras"][0][f"{xname}_std"]["translation_mm"]
    lines = [(f"{len(fit.ids) + len(fit.repeats)} pairs at {len(fit.ids)} distinct flange "
              "poses (a repeated pose counted once), " if fit.repeats else
              f"{len(fit.ids)} pairs, ") + f"{len(fit.outliers)} left out; pair scatter "
             f"{fit.sigma_mm:.3f} mm, {fit.sigma_deg:.3f} deg (one std per axis)",
             f"{xname}: at {t[0]:.3f} {t[1]:.3f} {t[2]:.3f} mm (std "
             + ", ".join("not identifiable" if v is None else f"{v:.3f}" for v in sd) + ")"]
    lines += [f"left out: {r}" for r in fit.outlier_reasons]
    v = Verdict.from_json(o.document["verdict"])
    if v.floor_line:
        lines.append(v.floor_line)
    return lines + _verdict_lines(v) + [f"wrote {o.path}"]


def handeye_photos_lines(o: HandeyePhotosOutcome) -> list[str]:
    """``vision-cal handeye PHOTOS/ --robot-poses``: the photos, the two transforms with
    their std, each photo predicted from the others, what limits it, and the verdict."""
    # the action that returned ``o`` imported it already
    from vision_cal.estimate.verdict import Verdict

    doc, fit = o.document, o.fit
    he = doc["handeye"]
    cam = doc["cameras"][0]
    lines = [f"{len(fit.views)} photos used, {len(fit.left_out)} left out, {len(o.skipped)} "
             f"skipped; board: {he['board']['describes']}; lens {cam['intrinsics']}"]
    for name, T, sd in ((fit.names[0], cam[fit.names[0]], cam[f"{fit.names[0]}_std"]),
                        (fit.names[1], doc[fit.names[1]], doc[f"{fit.names[1]}_std"])):
        t = T[0][3], T[1][3], T[2][3]
        lines.append(f"{name}: at {t[0]:.2f} {t[1]:.2f} {t[2]:.2f} mm (std "
                     + " ".join(f"{v:.2f}" for v in sd["translation_mm"]) + " mm, "
                     + " ".join(f"{v:.3f}" for v in sd["rotation_deg"]) + " deg)")
    for im in doc["images"]:
        if im["status"] == "ok":
            lines.append(f"  {im['file']}: residual {im['residual_px']:.2f} px; predicted from "
                         f"the others {im['heldout_px']:.2f} px ({im['heldout_mm']:.2f} mm at "
                         f"the board), stated {im['stated_px']:.2f} px")
        else:
            lines.append(f"  {im['file']}: {im['status']}: {im['reason']}")
    h = he["heldout"]
    lines.append(f"held-out photos: {h['rms_px']:.2f} px RMS ({h['rms_mm']:.2f} mm at the "
                 f"board), stated {h['stated_px']:.2f} px ({h['stated_mm']:.2f} mm)")
    lines.append(f"limited by: {he['limited_by']}")
    return lines + [Verdict.from_json(doc["verdict"]).text, f"wrote {o.path}"]


def joint_lines(o: JointCalibrated) -> list[str]:
    """``vision-cal calibrate --joint``: each placement's sheet pose and residual, the
    effects, each placement's verdict and the robot's."""
    # the action that returned ``o`` imported it already
    from vision_cal.estimate.verdict import Verdict

    doc = o.document
    lines = [f"{pl['folder']}: sheet at {pl['angle_deg']:.3f} deg, base "
             f"({pl['base_mm'][0]:.3f}, {pl['base_mm'][1]:.3f}) mm, rms "
             f"{pl['residual_rms_mm']:.4f} mm" for pl in doc["placements"]]
    lines.append("effects: " + (", ".join(e["name"] + (f"(joint {e['joint']})"
                                                       if "joint" in e else "")
                                          for e in doc["effects"]) or "none"))
    lines += [f"{pl['folder']}: {Verdict.from_json(pl['verdict']).text}"
              for pl in doc["placements"]]
    return lines + [f"verdict: {Verdict.from_json(doc['verdict']).text}"]


def summary_table(rows) -> str:
    """``vision-cal calibrate A/ B/``: one line per folder (summary.json's rows)."""
    def f(x):
        return "-" if x is None else f"{x:.4f}"

    lines = [f"{'folder':<28}{'status':<8}{'marks':>6}{'skipped':>8}{'rms [mm]':>10}"
             f"{'held-out':>10}  effects"]
    for r in rows:
        if r["status"] != "ok":
            lines.append(f"{r['folder'][-28:]:<28}{'failed':<8}  {r['reason']}")
            continue
        lines.append(f"{r['folder'][-28:]:<28}{'ok':<8}{r['marks']:>6}{r['skipped_photos']:>8}"
                     f"{f(r['residual_rms_mm']):>10}{f(r['validation_rms_mm']):>10}  "
                     f"{', '.join(r['effects']) or 'none'}")
    return "\n".join(lines)


def flange_camera_line(cam: dict) -> str:
    """T_flange_camera in words, with units: the camera's x and y in the flange frame with
    their std; its z is the height above the sheet's plane (SCARA motion is planar: the
    flange's own height, hence the camera's height above the flange, is not identifiable)."""
    t = cam["T_flange_camera"]
    sd = cam["T_flange_camera_std"]["translation_mm"]
    return (f"T_flange_camera: camera at x {t[0][3]:.3f} +- {sd[0]:.3f} mm, y {t[1][3]:.3f} +- "
            f"{sd[1]:.3f} mm in the flange frame; its height above the flange is not "
            f"identifiable (planar motion): z {t[2][3]:.3f} mm is its height above the "
            "sheet's plane")


def verify_lines(o: VerifyOutcome) -> list[str]:
    """``vision-cal verify``: each mark's error, the RMS and its bound, which parameters
    moved, ISO 9283 and the verdict with its reasons."""
    r = o.result
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
        lines += [f"  {name}: AP {v['AP_mm']:.4f} mm, RP {v['RP_mm']:.4f} mm ({v['n']} visits)"
                  for name, v in r.iso9283.items()]
    lines.append(f"verdict: {r.verdict}")
    lines += [f"  - {reason}" for reason in r.reasons]   # one finding or action a line
    others = [p.name for p in o.written if p != o.path]
    return lines + [f"wrote {o.path}" + (f" (and {', '.join(others)} beside it: the photos "
                                          "as measured)" if others else "")]


def loop_lines(o: LoopOutcome) -> list[str]:
    """``vision-cal loop``: the calibration's summary and the targets' table (Table 3)."""
    # the action that returned ``o`` imported it already
    from vision_cal.workflows.loop import format_table
    from vision_cal.report.summary import format_summary

    return [format_summary(o.calibration), "",
            "absolute error of each target, measured from the photographs (Table 3):",
            format_table(o.loop)]


def report_line(path: Path, photos: Path) -> str:
    """Where the report is, its size, and where the photos it links are."""
    return (f"report: {path.resolve()} ({path.stat().st_size / 1e6:.1f} MB; the photos it "
            f"links are in {photos.resolve()})")


def simulate_line(r: SimulateResult) -> str:
    """``vision-cal simulate``: the marks drawn (off the paper, on a printed marker) and the
    photos taken."""
    if r.blank:
        return (f"the blank sheet photographed from {len(r.photos)} places -> {r.out_dir}/ "
                "(truth.json: the markers as printed)")
    extra = []
    if r.off_paper:
        extra.append(f"{len(r.off_paper)} off the paper")
    if r.on_marker:
        extra.append(f"{len(r.on_marker)} on a printed marker")
    return (f"the simulated robot drew {r.n_marks} marks"
            + (f" ({', '.join(extra)})" if extra else "")
            + f"; {len(r.photos)} photos -> {r.out_dir}/ (truth.json: where they really are)")


def _print_lines(lines) -> None:
    for line in lines:
        print(line)


def _arm_camera(o: ArmCameraOutcome, quiet: bool) -> None:
    if not quiet:
        _print_lines(arm_camera_lines(o))


def _handeye_pairs(o: HandeyePairsOutcome, quiet: bool) -> None:
    if not quiet:
        _print_lines(handeye_pairs_lines(o))


def _handeye_photos(o: HandeyePhotosOutcome, quiet: bool) -> None:
    if not quiet:
        _print_lines(handeye_photos_lines(o))


def _outputs_named(o: OutputsNamed, quiet: bool) -> None:
    if not quiet:
        print("outputs: " + ", ".join(f"{f} -> {out}" for f, out in o.outputs))


def _survey_found(o: SurveyFound, quiet: bool) -> None:
    if not quiet:
        print(f"measuring against the sheet as surveyed: {o.path}")


def _survey_not_applied(o: SurveyNotApplied, quiet: bool) -> None:
    """Said even when quiet (stderr): the survey beside the folder is not used."""
    print(f"not applying the sheet as surveyed ({o.path}): {o.status}: {o.reason}",
          file=sys.stderr)


def _folder_calibrated(o: FolderCalibrated, quiet: bool) -> None:
    """The summary, then the photos skipped and what was inferred (stderr), the report and
    the file written (said even when quiet)."""
    run = o.run
    if not quiet:
        # the action that returned ``o`` imported it already
        from vision_cal.report.summary import format_summary

        print(format_summary(run.document, reference=run.session.raw.get("reference")))
    for im in run.document.get("images", []):
        if im.get("status") != "ok":
            print(f"vision-cal: warning: {o.folder}/{im['file']}: skipped: {im.get('reason')}",
                  file=sys.stderr)
    meas = run.measurement
    for note in (meas.inferred_notes if meas is not None else ()):  # no images list
        print(f"vision-cal: warning: {o.folder}: {note}", file=sys.stderr)
    if o.report is not None:
        print(f"report: {o.report} ({o.report.stat().st_size / 1e6:.1f} MB)")
    print(f"wrote {run.out_path}")


def _folder_failed(o: FolderFailed, quiet: bool) -> None:
    print(f"vision-cal: error: {o.folder}: {o.reason}", file=sys.stderr)


def _calibrate(o: CalibrateOutcome, quiet: bool) -> int:
    if o.summary is not None:   # several folders: the table even when quiet
        print(summary_table(o.rows))
        print(f"wrote {o.summary}")
    return 1 if o.failures else 0


def _joint(o: JointCalibrated, quiet: bool) -> None:
    if not quiet:
        _print_lines(joint_lines(o))
    print(f"wrote {o.path}")


def _verify(o: VerifyOutcome, quiet: bool) -> None:
    for w in o.warnings:   # --force: the check compared beyond what was calibrated
        print(f"vision-cal: warning: {w}", file=sys.stderr)
    if not quiet:
        _print_lines(verify_lines(o))


def _loop(o: LoopOutcome, quiet: bool) -> None:
    if not quiet:
        _print_lines(loop_lines(o))
    if o.report is not None:   # said even when quiet: where to look
        print(report_line(o.report, o.out))


def _history(o: HistoryOutcome, quiet: bool) -> None:
    if not quiet:
        # the action that returned ``o`` imported it already
        from vision_cal.report.history import history_table

        print(history_table(list(o.rows)))
        _print_lines(f"wrote {p}" for p in o.written)


def _simulate(r: SimulateResult, quiet: bool) -> None:
    if not quiet:
        print(simulate_line(r))



def sheet_lines(o: SheetOutcome) -> list[str]:
    """``vision-cal sheet``: the page, the markers, the files, and how to print."""
    layout = o.layout
    spec = getattr(layout, "spec", None)    # a ChArUco board (sheet/charuco.py)
    if spec is not None:
        return [f"sheet {layout.sheet_id}: ChArUco {spec.squares[0]}x{spec.squares[1]} "
                f"squares of {spec.square_mm:g} mm, {len(layout.markers)} "
                f"{layout.dictionary} markers of {spec.marker_mm:g} mm on {layout.page} "
                f"{layout.orientation} -> " + ", ".join(str(p) for p in o.paths.values()),
                f"print at 100 % (actual size) and check that a square measures "
                f"{spec.square_mm:g} mm; glue it flat on a rigid plate"]
    return [f"sheet {layout.sheet_id}: {layout.page} {layout.orientation} "
            f"{layout.size_mm[0]:g} x {layout.size_mm[1]:g} mm, {len(layout.markers)} "
            f"{layout.dictionary} markers of {layout.marker_mm:g} mm -> "
            + ", ".join(str(p) for p in o.paths.values()),
            "print at 100 % (actual size) and check that both bars measure 100.0 mm"]


def survey_lines(o: SurveyOutcome) -> list[str]:
    """``vision-cal survey``: the verdict, the halves' agreement (issue 37) and what limits
    it (what would resolve it, when it claims no field)."""
    v = o.survey["verdict"]
    head = "limited by" if v["status"] in ("good", "limited") else "to resolve"
    return ([f"{o.path}: {v['status']}: {v['text']}"]
            + ([f"  replication: {v['replication']}"] if v.get("replication") else [])
            + [f"  {head}: {line}" for line in v["limits"]])


def _render(o: RenderOutcome, quiet: bool) -> None:
    print(o.folder)   # even when quiet: the folder to calibrate next


def _robot_template(o: RobotTemplateOutcome, quiet: bool) -> None:
    if o.path is None:   # the text itself is the output
        print(o.text, end="")
    elif not quiet:
        print(f"wrote {o.path}: edit the fields marked EDIT" if not o.simulated
              else f"wrote {o.path}: the `hidden` block is what the simulated robot hides")


def _sheet(o: SheetOutcome, quiet: bool) -> None:
    if not quiet:
        _print_lines(sheet_lines(o))


def _survey(o: SurveyOutcome, quiet: bool) -> int:
    """The lines; exit 1 when the survey failed (its solve stopped: no result), said on
    stderr even when quiet."""
    failed = o.survey["verdict"]["status"] == "failed"
    if not quiet:
        _print_lines(survey_lines(o))
    elif failed:
        print(survey_lines(o)[0], file=sys.stderr)
    return 1 if failed else 0



def _export(o: ExportOutcome, quiet: bool) -> None:
    for w in o.warnings:
        print(w, file=sys.stderr)
    for w in o.said:   # --force: exported beyond what was calibrated
        print(f"vision-cal: warning: {w}", file=sys.stderr)
    if not quiet:
        _print_lines(f"wrote {p}" for p in o.written)


def _init(o: InitOutcome, quiet: bool) -> None:
    for w in o.warnings:
        print(f"vision-cal: warning: {w}", file=sys.stderr)
    if o.out is None:   # the session itself is the output
        sys.stdout.write(json.dumps(o.session, indent=2) + "\n")
    if not quiet:
        print(o.summary, file=sys.stderr)


def locate_lines(o: LocateOutcome) -> list[str]:
    """``vision-cal locate --pixel``: the pixel in the robot and sheet frames, and the joint
    command that reaches it (with --robot)."""
    p, j = o.point, o.joint
    if o.flange:   # a camera on any arm's flange (issue 40)
        return [f"pixel {p.pixel[0]:g} {p.pixel[1]:g} at z {p.z_mm:g} mm (camera {o.camera}, "
                f"flange pose {o.flange})",
                f"  robot frame: x {p.robot_mm[0]:.4f} y {p.robot_mm[1]:.4f} z "
                f"{p.robot_mm[2]:.4f} mm  (std {p.robot_std_mm[0]:.4f} {p.robot_std_mm[1]:.4f} "
                f"{p.robot_std_mm[2]:.4f} mm)",
                f"  board frame: x {p.sheet_mm[0]:.4f} y {p.sheet_mm[1]:.4f} z "
                f"{p.sheet_mm[2]:.4f} mm"]
    lines = [f"pixel {p.pixel[0]:g} {p.pixel[1]:g} at z {p.z_mm:g} mm (camera {o.camera})",
             f"  robot frame: x {p.robot_mm[0]:.4f} y {p.robot_mm[1]:.4f} z "
             f"{p.robot_mm[2]:.4f} mm  (std {p.robot_std_mm[0]:.4f} {p.robot_std_mm[1]:.4f} mm)",
             f"  sheet frame: x {p.sheet_mm[0]:.4f} y {p.sheet_mm[1]:.4f} mm"]
    if j is not None:
        lines.append(f"  joint command (compensated, elbow {o.elbow:+d}): q1 {j.q_deg[0]:.4f} "
                     f"q2 {j.q_deg[1]:.4f} deg, approach {j.approach[0]:+d} {j.approach[1]:+d}"
                     if j.status == "ok" else f"  joint command: none ({j.reason})")
    return lines


def _locate(o: LocateOutcome, quiet: bool) -> int:
    for w in o.warnings:   # --force: the extrapolation (also in the CSV); pixels not located
        print(f"vision-cal: warning: {w}", file=sys.stderr)
    if o.error:
        print(f"vision-cal: error: {o.error}", file=sys.stderr)
    elif o.point is not None:   # one pixel: the answer itself, even when quiet
        _print_lines(locate_lines(o))
    elif o.csv_text is not None:
        sys.stdout.write(o.csv_text)
    elif not quiet:
        print(f"located {o.n} pixels -> {o.path}")
    return o.exit_code


def stage_lines(o: StageDesigned) -> list[str]:
    """``vision-cal design``: the survey that goes with the plan, the plan's size and what
    it is for, the files written."""
    r = o.result
    lines = list(o.pilot_note)
    if o.survey_copy is not None:
        lines.append(f"the sheet as surveyed ({o.survey}) goes with the plan: {o.survey_copy}")
    if o.survey_not_applied:   # issue 37: a survey that claims no print field
        lines.append(f"not applying the sheet as surveyed ({o.survey}): "
                     f"{o.survey_not_applied}")
    lines.append(f"{r.stage} plan: {r.n_marks} marks, {r.duration_s:.1f} s of motion")
    if r.stage == "pilot":
        lines.append(f"every mark stays {r.info['worst_case_clearance_mm']:.1f} mm clear of "
                     f"markers and edges for {r.info['placements_checked']} placements within "
                     "the robot file's placement_tolerance")
    elif r.stage == "verify":
        lines.append(f"a check of {o.verify}: draw it on a fresh sheet, photograph it into "
                     f"{o.out}, then: vision-cal verify {o.verify} {o.out}")
    else:
        lines.append(f"placed with the pilot's model, {r.info['safety_mm']:.1f} mm of safety")
        beyond = r.info.get("beyond_valid_for") or []
        if beyond:   # by design: the informative plan identifies what the pilot could not
            lines.append("the pilot's model is this plan's starting model (not the nominal: "
                         "that stays the robot file); the plan goes beyond what the pilot saw, "
                         "by design (" + ", ".join(b["field"] for b in beyond) + "): its "
                         "calibration identifies them (session.json design.beyond_valid_for)")
    return lines + [f"wrote {p}" for p in (r.session_path, r.trajectory_path, r.program_path)
                    if p is not None]


def camera_poses_lines(o: CameraPosesDesigned) -> list[str]:
    """``vision-cal design --camera-on-arm``: the poses, where the photos go, what next."""
    return [f"camera poses: {o.n_poses}, {o.repeats} of them taken twice (the robot's "
            f"repeatability, measured) ({o.mount} mount); put the photos beside "
            f"{o.session} (and your camera's lens in it if you know it: camera: size_px, K, "
            f"dist), then vision-cal handeye {o.out} --out CAL/",
            f"wrote {o.session}", f"wrote {o.program}"]


def _stage(o: StageDesigned, quiet: bool) -> None:
    for w in o.result.info.get("warnings", []):
        print(f"vision-cal: warning: {w}", file=sys.stderr)
    if not quiet:
        _print_lines(stage_lines(o))


def _placements(o: PlacementsDesigned, quiet: bool) -> None:
    if not quiet:
        _print_lines(f"{p['folder']}: {p['instruction']}" for p in o.placements)


def _camera_poses(o: CameraPosesDesigned, quiet: bool) -> None:
    if not quiet:
        _print_lines(camera_poses_lines(o))


def _plan(o: PlanOutcome, quiet: bool) -> int:
    if o.trust_warning:
        print(o.trust_warning, file=sys.stderr)
    if o.program is not None and not quiet:
        print(f"wrote {o.program}")
    for w in o.warnings:
        print(f"vision-cal: warning: {w}", file=sys.stderr)
    if not quiet:
        print(o.summary)
    if o.error:
        print(f"vision-cal: error: {o.error}", file=sys.stderr)
    return o.exit_code

#: the printer of each outcome's type, by its module and name
PRINTERS = {"vision_cal.actions.arm_camera.ArmCameraOutcome": _arm_camera,
            "vision_cal.actions.verify.VerifyOutcome": _verify,
            "vision_cal.actions.loop.LoopOutcome": _loop,
            "vision_cal.actions.history.HistoryOutcome": _history,
            "vision_cal.world.rehearse.SimulateResult": _simulate,
            "vision_cal.actions.render.RenderOutcome": _render,
            "vision_cal.actions.robot_template.RobotTemplateOutcome": _robot_template,
            "vision_cal.actions.sheet.SheetOutcome": _sheet,
            "vision_cal.actions.survey.SurveyOutcome": _survey,
            "vision_cal.actions.export.ExportOutcome": _export,
            "vision_cal.actions.init.InitOutcome": _init,
            "vision_cal.actions.locate.LocateOutcome": _locate,
            "vision_cal.actions.design.StageDesigned": _stage,
            "vision_cal.actions.design.PlacementsDesigned": _placements,
            "vision_cal.actions.design.CameraPosesDesigned": _camera_poses,
            "vision_cal.actions.plan.PlanOutcome": _plan,
            "vision_cal.actions.handeye.HandeyePairsOutcome": _handeye_pairs,
            "vision_cal.actions.handeye.HandeyePhotosOutcome": _handeye_photos,
            "vision_cal.actions.calibrate.OutputsNamed": _outputs_named,
            "vision_cal.actions.calibrate.SurveyFound": _survey_found,
            "vision_cal.actions.calibrate.SurveyNotApplied": _survey_not_applied,
            "vision_cal.actions.calibrate.FolderCalibrated": _folder_calibrated,
            "vision_cal.actions.calibrate.FolderFailed": _folder_failed,
            "vision_cal.actions.calibrate.CalibrateOutcome": _calibrate,
            "vision_cal.actions.calibrate.JointCalibrated": _joint}
