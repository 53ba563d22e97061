"""The closed loop: plan, simulate, draw, photograph, measure - before and after.

What ``vision-cal loop SCENE.yaml --out DIR`` (and ``make demo``) runs, the seed paper's
Table 3 for every target:

0. with the scene's ``survey`` block: photograph the blank sheet of the same world (seed,
   print, lens) from several places, tilted, before the robot draws  -> DIR/survey_photos/
   and survey it (``vision-cal survey``'s code)                      -> DIR/survey/survey.json
1. render the scene's calibration session (a robot with hidden effects draws the plan;
   pyrender photographs the sheet)                                   -> DIR/session/
2. calibrate it from the photographs (measure, fit, diagnose)        -> DIR/calibration/
   against the survey when it measured the print (a field claimed, or the print found on
   its layout: ``measure.replicate.measures_the_print``, as ``vision-cal calibrate`` does)
3. choose validation targets: the sheet origin (as in the paper), a grid of points over
   the reachable free paper and a short drawn path                   -> DIR/targets.csv
4. plan them with the nominal and with the calibrated model (every effect found
   compensated)                                                      -> DIR/plan_*.csv
5. run both plans through the simulated controller on the *true* robot, draw them on
   fresh sheets, photograph each finished sheet                      -> DIR/sheet_*/
6. measure those photographs and report each target's absolute error (measured minus
   target) before and after                                          -> DIR/loop.json

The errors come from the photographs, not from the simulator. The command (:func:`loop`:
its request, :func:`run_loop` in a locked output folder, then the report, and its outcome
that prints itself) comes first, the loop's stages after it.
"""

from __future__ import annotations

import base64
import os
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from vision_cal.actions.console import say
from vision_cal.actions.measure_folder import measure_folder
from vision_cal.actions.pipeline import calibrate_dataset
from vision_cal.dataset.csvio import write_plan, write_targets
from vision_cal.dataset.io import atomic_write_json, read_json
from vision_cal.dataset.marker_geometry import quiet_boxes_mm
from vision_cal.dataset.out_folder import writing_into
from vision_cal.dataset.session import load_session
from vision_cal.errors import VisionCalError
from vision_cal.estimate.paper import pilot_params
from vision_cal.measure.replicate import measures_the_print
from vision_cal.measure.survey import SURVEY_FILE, applicable, run_survey
from vision_cal.model.kinematics import ScaraParams, inverse
from vision_cal.model.motion import JOINT_LIMITS_DEG, TRAJECTORY_DT_S
from vision_cal.model.rms import rms
from vision_cal.model.robot import RobotModel
from vision_cal.plan.calibration_plan import sheet_clearance_mm
from vision_cal.plan.compensate import PlannedTarget, plan_targets, to_planned_marks
from vision_cal.plan.trajectory import plan_trajectory
from vision_cal.progress import stage_line
from vision_cal.report.html import write_report
from vision_cal.report.plots import loop_joints, loop_paths
from vision_cal.report.summary import format_summary, survey_line
from vision_cal.world.dataset import render_dataset
from vision_cal.world.scene import load_scene


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


#: the fewest survey photos worth a rendering process of their own
PHOTOS_PER_PROCESS = 8


def default_targets(sheet, params: ScaraParams, *, n_grid: int = 20, n_path: int = 12,
                    clearance_mm: float = 8.0, elbow: int = 1, rng=None):
    """Ids and sheet points (N, 2): the origin, a grid over the reachable free paper, and a
    short path (an arc of ``n_path`` points) - all clear of markers and edges."""
    rng = np.random.default_rng(0 if rng is None else rng)
    lim = np.array(JOINT_LIMITS_DEG) * 0.95  # a margin for the effects and the overshoot
    x0, y0, x1, y1 = sheet.extent_mm

    def usable(p):
        p = np.atleast_2d(p)
        ok = sheet_clearance_mm(sheet, p) >= clearance_mm
        r = np.hypot(*(p - np.array(params.base_mm)).T)
        lo = abs(params.L1_mm - params.L2_mm) + 40.0
        hi = params.L1_mm + params.L2_mm - 40.0
        ok &= (r >= lo) & (r <= hi)
        if ok.any():
            q = inverse(params, p[ok], elbow=elbow)
            inside = np.all((q >= lim[:, 0]) & (q <= lim[:, 1]), axis=1)
            ok[np.flatnonzero(ok)[~inside]] = False
        return ok

    ids, pts = [], []
    if usable([0.0, 0.0])[0]:
        ids.append("origin")
        pts.append([0.0, 0.0])
    # grid: a fine lattice of usable points, then a greedy spread pick
    gx, gy = np.meshgrid(np.linspace(x0 + 20, x1 - 20, 40), np.linspace(y0 + 20, y1 - 20, 30))
    cand = np.column_stack([gx.ravel(), gy.ravel()])
    cand = cand[usable(cand)]
    if len(cand) < n_grid:
        raise VisionCalError(f"only {len(cand)} usable target points on the reachable paper")
    chosen = [cand[np.argmin(np.hypot(*(cand - cand.mean(axis=0)).T))]]
    for _ in range(n_grid - 1):
        d = np.min(np.linalg.norm(cand[:, None] - np.array(chosen + pts)[None], axis=2), axis=1)
        chosen.append(cand[np.argmax(d)])
    for k, p in enumerate(chosen):
        ids.append(f"g{k:02d}")
        pts.append(p.tolist())
    # path: an arc of radius 35 mm about a usable centre, every point usable
    taken = np.array(pts)
    for c in rng.permutation(cand):
        a = np.linspace(0, np.pi, n_path)
        arc = c + 35.0 * np.column_stack([np.cos(a), np.sin(a)])
        if usable(arc).all() and np.min(np.linalg.norm(arc[:, None] - taken[None], axis=2)) > 10:
            for k, p in enumerate(arc):
                ids.append(f"p{k:02d}")
                pts.append(p.tolist())
            break
    xy = np.array(pts)
    inverse(params, xy, elbow=elbow)  # raises if any is out of reach
    return ids, xy


def landing_note(sheet, model, planned) -> str:
    """Why a planned mark was not measured: where the calibrated ``model`` says the pen
    landed (off the paper, on a printed marker), else a generic reason."""
    generic = "not measured on the photo (not found or not associated)"
    if planned.q_deg is None:
        return generic
    xy = model.predict(np.array([planned.q_deg], float), np.array([planned.approach], float))
    x0, y0, x1, y1 = sheet.extent_mm
    where = f"the calibrated model puts it at ({xy[0, 0]:.1f}, {xy[0, 1]:.1f}) mm"
    if not (x0 <= xy[0, 0] <= x1 and y0 <= xy[0, 1] <= y1):
        return f"off the paper: {where}"
    if sheet_clearance_mm(sheet, xy)[0] <= 0.0:
        return f"on a printed marker: {where}"

    # a dot touching a marker's quiet zone is masked with the marker (measure/dots.py)
    boxes = quiet_boxes_mm(sheet)
    r = 1.0   # about a pen mark's radius, mm
    if len(boxes) and np.any(np.all((xy[0] >= boxes[:, :2] - r) & (xy[0] <= boxes[:, 2:] + r),
                                    axis=1)):
        return f"on a printed marker's quiet zone (masked with the marker): {where}"
    return f"{generic}; {where}"


def run_loop(scene_path, *, out_dir, jobs: int | None = None, progress: bool = False,
             elbow: int = 1, photographer=None):
    """Run the closed loop for a scene file; writes ``DIR/loop.json`` and returns
    ``(loop document, CalibrationRun)``."""
    out = Path(out_dir)
    scene = load_scene(scene_path)
    stages = {}
    render_jobs = jobs or os.cpu_count() or 1
    run, survey = _calibrate_scene(scene, out, jobs=jobs, render_jobs=render_jobs,
                                   progress=progress, photographer=photographer, stages=stages)
    calibrated = run.model                      # kept in memory, not read back
    nominal = RobotModel(run.session.robot.params)
    sheet = run.session.sheet
    ids, xy = default_targets(sheet, calibrated.params, elbow=elbow)
    write_targets(out / "targets.csv", ids, xy)
    targets = dict(zip(ids, xy))
    t = time.perf_counter()
    plans = _plan_both(out, ids, xy, nominal, calibrated, elbow=elbow)
    stages["plan (both models)"] = time.perf_counter() - t
    results, controller = {}, {}
    for k, name in enumerate(("before", "after")):
        truth, m = _draw_and_measure(
            scene, k, name, plans[name], targets, out, jobs=jobs, render_jobs=render_jobs,
            progress=progress, photographer=photographer, stages=stages)
        controller[name] = truth.get("controller_report")
        results[name] = _target_results(plans[name], m, targets, sheet, calibrated,
                                        landed=_landed(truth))
    doc = _loop_document(scene_path, ids, targets, results, stages, controller, run)
    if survey is not None:
        doc["survey"] = survey
    if progress:
        stage_line("loop", sum(stages.values()), note="; ".join(
            f"{k} {v:.1f} s" for k, v in stages.items()))

    doc["trajectories"] = loop_trajectories(doc)   # what the report's Fig. 10 draws
    doc["paths_png"] = base64.b64encode(loop_paths(doc)).decode("ascii")
    doc["joints_png"] = base64.b64encode(loop_joints(doc)).decode("ascii")
    atomic_write_json(out / "loop.json", doc)
    return doc, run


def _survey_sheet(scene, out: Path, *, render_jobs: int, progress: bool, photographer,
                  stages: dict) -> dict | None:
    """Step 0, with the scene's ``survey`` block (None without): the blank sheet of the same
    world photographed from the survey's places into ``out/survey_photos``, surveyed by
    ``vision-cal survey``'s code into ``out/survey/survey.json``; loop.json's ``survey``:
    the photos, the file, its verdict, its claim (``status``, ``reason``) and ``used``:
    whether the calibration measures the marks against it (it measured the print: a field
    claimed, or the print found on its layout; a failed, unresolved or unreplicated survey
    is not used, and the verdict then says the print is not measured). Each step's seconds
    go to ``stages``."""
    if scene.survey is None:
        return None
    t = time.perf_counter()
    # a rendering process's start (imports, its OpenGL context) costs about what 2-3 photos
    # do: the demo's six survey photos render here (rendered and surveyed in 11.5 CPU-s,
    # 16.6 with two rendering processes)
    jobs = max(1, min(render_jobs, scene.survey.n_views // PHOTOS_PER_PROCESS))
    photos = render_dataset(scene.survey_photos(), out / "survey_photos", progress=progress,
                            photographer=photographer, pilot=pilot_params, jobs=jobs)
    stages["render survey photos"] = time.perf_counter() - t
    t = time.perf_counter()
    (out / "survey").mkdir(exist_ok=True)
    path = out / "survey" / SURVEY_FILE
    try:
        doc = run_survey(photos, photos / "session.json", out / "survey")
    except VisionCalError as e:   # too few places, or views that do not fix the sheet
        doc, claim, path = {"verdict": {"status": "failed", "text": e.reason}}, None, None
    else:
        claim = applicable(path)
    stages["survey"] = time.perf_counter() - t
    verdict = doc.get("verdict") or {}
    if progress:
        stage_line("survey", stages["survey"], n=len(doc.get("photos") or []), unit="photo",
                   note=verdict.get("status", ""))
    return {"photos": str(photos), "file": None if path is None else str(path),
            "n_photos": len(doc.get("photos") or []),
            "n_used": sum(p.get("status") == "ok" for p in doc.get("photos") or []),
            "verdict": verdict.get("text"),
            "status": claim.status if claim else "failed",
            "reason": claim.reason if claim else verdict.get("text"),
            "used": bool(claim and measures_the_print(claim))}


def _calibrate_scene(scene, out: Path, *, jobs, render_jobs: int, progress: bool,
                     photographer, stages: dict):
    """Steps 0-2: the sheet surveyed (the scene's ``survey`` block: :func:`_survey_sheet`),
    the scene's calibration session rendered into ``out/session`` and calibrated into
    ``out/calibration``, against the survey when it measured the print; return the
    ``CalibrationRun`` and loop.json's ``survey`` (None without a survey block). Each
    step's seconds go to ``stages``."""
    survey = _survey_sheet(scene, out, render_jobs=render_jobs, progress=progress,
                           photographer=photographer, stages=stages)
    t = time.perf_counter()
    session_dir = render_dataset(scene, out / "session", progress=progress,
                                 photographer=photographer, pilot=pilot_params,
                                 jobs=render_jobs)
    stages["render calibration session"] = time.perf_counter() - t
    t = time.perf_counter()
    run = calibrate_dataset(session_dir, out_dir=out / "calibration", jobs=jobs,
                            progress=progress,
                            survey=survey["file"] if survey and survey["used"] else None)
    stages["measure + calibrate + diagnose"] = time.perf_counter() - t
    if progress:
        stage_line("measure + calibrate + diagnose", stages["measure + calibrate + diagnose"],
                   n=len(run.document.get("marks", {})), unit="mark")
    return run, survey


def _plan_both(out: Path, ids, xy, nominal, calibrated, *, elbow: int) -> dict:
    """Step 4: the targets planned with the nominal model ("before") and the calibrated one
    ("after"), each written to ``out/plan_<name>.csv``; name -> its planned targets."""
    plans = {}
    for name, model in (("before", nominal), ("after", calibrated)):
        planned = plan_targets(model, ids, xy, elbow=elbow)
        write_plan(out / f"plan_{name}.csv", [p.to_row() for p in planned])
        plans[name] = planned
    return plans


def _draw_and_measure(scene, k: int, name: str, planned, targets: dict, out: Path, *, jobs,
                      render_jobs: int, progress: bool, photographer, stages: dict):
    """Step 5-6 for one plan: the true robot draws ``planned`` on a fresh sheet (seed
    ``scene.seed + 1000 + k``, the arm parked away) photographed into ``out/sheet_<name>``,
    measured into ``out/measure_<name>``; return (the world's truth.json: the controller's
    report, where the marks landed; the measurement). Each step's seconds go to ``stages``."""
    marks = to_planned_marks(planned)
    sc = scene.with_overrides(seed=scene.seed + 1000 + k, mode="single")
    # the arm is moved away before the finished sheet is photographed
    sc = replace(sc, photos=replace(sc.photos, extra_files=(), arm_parked=False))
    t = time.perf_counter()
    sheet_dir = render_dataset(sc, out / f"sheet_{name}", progress=progress, plan=marks,
                               targets_mm=targets, photographer=photographer,
                               jobs=render_jobs)
    stages[f"simulate + draw + photograph ({name})"] = time.perf_counter() - t

    truth = read_json(sheet_dir / "truth.json")
    t = time.perf_counter()
    m = measure_folder(load_session(sheet_dir), out_dir=out / f"measure_{name}", jobs=jobs,
                       progress=progress)
    stages[f"measure ({name})"] = time.perf_counter() - t
    return truth, m


def _landed(truth: dict) -> dict:
    """Mark id -> where the simulated pen really landed when no photo can show it (the
    world's truth.json: ``off_paper``, ``on_marker``)."""
    out = {i: "landed on a printed marker (truth.json)" for i in truth.get("on_marker") or ()}
    out.update({i: "landed off the paper (truth.json)" for i in truth.get("off_paper") or ()})
    return out


def _target_results(planned, m, targets: dict, sheet, calibrated, *,
                    landed: dict | None = None) -> dict:
    """Target id -> its result in loop.json: measured and its error against the target,
    not planned, or not found (with the reason: where the simulated pen really landed,
    ``landed``, when it is off the paper or on a marker; else the measurement's); the
    joints commanded when planned."""
    res = {}
    for p in planned:
        if p.status != "ok":
            res[p.id] = {"status": "not planned", "reason": p.reason}
        elif p.id in m.marks:
            e = np.asarray(m.marks[p.id].xy_mm) - targets[p.id]
            res[p.id] = {"status": "ok", "measured_mm": np.asarray(m.marks[p.id].xy_mm).tolist(),
                         "error_mm": e.tolist(), "error_norm_mm": float(np.hypot(*e))}
        else:
            # where the simulated pen really landed (no photo shows it), the
            # measurement's own reason (it saw the photo), else where the calibrated model
            # says the pen landed
            why = (landed or {}).get(p.id) or m.refused.get(p.id)
            res[p.id] = {"status": "not found",
                         "reason": str(why) if why else landing_note(sheet, calibrated, p)}
        if p.status == "ok":
            res[p.id].update(q_deg=list(p.q_deg), approach=list(p.approach))
    return res


def _loop_document(scene_path, ids, targets: dict, results: dict, stages: dict,
                   controller: dict, run) -> dict:
    """loop.json without its figures: every target's row before and after, the summary
    (RMS and max of the measured errors), the stages' seconds, the controllers' reports."""
    rows = []
    for tid in ids:
        b, a = results["before"][tid], results["after"][tid]
        rows.append({"id": tid, "target_mm": targets[tid].tolist(),
                     "before_error_mm": b.get("error_norm_mm"),
                     "after_error_mm": a.get("error_norm_mm"),
                     "before": b, "after": a})
    after = np.array([r["after_error_mm"] for r in rows if r["after_error_mm"] is not None])
    before = np.array([r["before_error_mm"] for r in rows if r["before_error_mm"] is not None])
    return {
        "format": "vision-cal/loop/1", "scene": str(scene_path),
        "targets": rows,
        "summary": {
            "n_targets": len(rows),
            "before": {"n_measured": int(len(before)),
                       "rms_mm": rms(before) if len(before) else None,
                       "max_mm": float(before.max()) if len(before) else None},
            "after": {"n_measured": int(len(after)),
                      "rms_mm": rms(after) if len(after) else None,
                      "max_mm": float(after.max()) if len(after) else None},
        },
        "stages_s": stages,
        "controller": controller,
        "calibration": str(run.out_path),
        "home_deg": [float(v) for v in run.session.robot.home_deg],
    }


def format_table(doc: dict) -> str:
    """The Table-3 comparison for every target."""
    lines = [f"{'target':<8}{'x [mm]':>9}{'y [mm]':>9}{'before [mm]':>16}{'after [mm]':>16}"]
    reasons: dict[str, int] = {}

    def cell(r, side, v, fmt):
        if v is not None:
            return fmt.format(v)
        why = (r[side] or {}).get("reason") or (r[side] or {}).get("status", "not measured")
        k = reasons.setdefault(why, len(reasons) + 1)
        return f"{r[side]['status']} ({k})"   # every missing value says why, below

    for r in doc["targets"]:
        lines.append(f"{r['id']:<8}{r['target_mm'][0]:>9.2f}{r['target_mm'][1]:>9.2f}"
                     f"{cell(r, 'before', r['before_error_mm'], '{:.3f}'):>16}"
                     f"{cell(r, 'after', r['after_error_mm'], '{:.4f}'):>16}")
    for why, k in reasons.items():
        lines.append(f"  ({k}) {why}")
    s = doc["summary"]
    c = (doc.get("controller") or {}).get("after")
    if c:
        lines.append(f"simulated {c['controller']} controller: tracking RMS "
                     f"{c['tracking_rms_deg'][0]:.4f} / {c['tracking_rms_deg'][1]:.4f} deg, settle "
                     f"residual max {max(c['settle_residual_max_deg']):.1e} deg, "
                     f"{c['duration_s']:.1f} s of motion")
    sv = doc.get("survey")
    if sv:
        lines.append(survey_line(sv))
    for k in ("before", "after"):
        v = s[k]
        if v["rms_mm"] is not None:
            lines.append(f"{k}: RMS {v['rms_mm']:.4f} mm, max {v['max_mm']:.4f} mm over "
                         f"{v['n_measured']} of {s['n_targets']} targets measured")
    return "\n".join(lines)


def loop_trajectories(loop: dict) -> dict:
    """loop.json ``trajectories``: ``dt_s`` and, for ``before`` / ``after``, ``t_s`` (K,)
    and ``q_deg`` (K, 2) of the targets planned with that model, from ``home_deg``."""
    home = loop.get("home_deg", (0.0, 0.0))
    out: dict = {"dt_s": TRAJECTORY_DT_S}
    for name in ("before", "after"):
        planned = [PlannedTarget(r["id"], tuple(r["target_mm"]), tuple(r[name]["q_deg"]),
                                 tuple(int(s) for s in r[name]["approach"]))
                   for r in loop["targets"] if "q_deg" in r[name]]
        if not planned:
            continue
        tr = plan_trajectory(to_planned_marks(planned), home_deg=home)
        out[name] = {"t_s": np.asarray(tr.t_s, float).tolist(),
                     "q_deg": np.asarray(tr.q_deg, float).tolist()}
    return out
