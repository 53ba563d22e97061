"""The planning action (``vision-cal plan``): joint commands that hit sheet targets with a
calibrated (or the nominal) model, the failed targets' report, and optionally the
reference trajectory and a robot program, written together or not at all."""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path

from vision_cal.actions.console import error, warn

from vision_cal.dataset.calibration import load_calibration
from vision_cal.dataset.covariance import load_covariance
from vision_cal.dataset.csvio import (failed_report_path, read_target_theta, read_targets,
                                      write_failed_targets, write_plan)
from vision_cal.dataset.io import distinct_outputs, written_together
from vision_cal.dataset.out_folder import output_file_of_kind, replacing_files
from vision_cal.dataset.robot import load_robot_file
from vision_cal.dataset.trust import refuse_unreliable
from vision_cal.dataset.valid_for import check as check_valid_for
from vision_cal.dataset.valid_for import enforce as enforce_valid_for
from vision_cal.dataset.valid_for import of as valid_for_of
from vision_cal.dataset.valid_for import per_item as outside_per_item
from vision_cal.errors import EXIT_PARTIAL, VisionCalError
from vision_cal.measure.printed import targets_on_print
from vision_cal.model.motion import JOINT_LIMITS_DEG
from vision_cal.plan.compensate import plan_targets, to_planned_marks, write_plan_trajectory
from vision_cal.plan.extrapolation import beyond_deg, std_limit_mm
from vision_cal.plan.orient import controller_tool_mm, plan_poses
from vision_cal.plan.trajectory import check_length
from vision_cal.plan.uncertainty import target_std
from vision_cal.program import KINDS as PROGRAM_KINDS
from vision_cal.program import check_program, program_path, program_points, write_program


@dataclass(frozen=True)
class PlanRequest:
    """What ``vision-cal plan`` was asked (the command's arguments, see its ``--help``)."""

    calibration: str                      # calibration.json to plan with
    targets: str                          # TARGETS.csv: id,x_mm,y_mm (+ theta_deg)
    out: str                              # PLAN.csv
    model: str = "calibrated"             # or "nominal" (the 'before' column)
    elbow: int = 1
    approach: tuple[int, int] = (1, 1)
    trajectory: str | None = None         # TRAJ.csv, 16 ms samples
    program: str | None = None            # one of vision_cal.program.KINDS (needs robot)
    home: tuple[float, float] | None = None
    robot: str | None = None              # ROBOT.yaml
    force: bool = False                   # plan with a 'not reliable' calibration
    approach4: int = 1
    quiet: bool = False


@dataclass(frozen=True)
class PlanOutcome:
    """What ``vision-cal plan`` did, for the console, in the order it is said: the
    calibration's trust (``--force`` over an unreliable one), the program written, the
    warnings (targets not planned, on the print, beyond ``valid_for``), the summary, and the
    error when nothing could be planned (exit code 1); ``partial``: some targets were not
    planned (exit code :data:`vision_cal.errors.EXIT_PARTIAL`: PLAN.failed.csv lists them)."""

    summary: str
    trust_warning: str | None = None
    program: Path | None = None
    warnings: tuple[str, ...] = ()
    error: str | None = None
    partial: bool = False

    @property
    def exit_code(self) -> int:
        return 1 if self.error else EXIT_PARTIAL if self.partial else 0

    def show(self, quiet: bool = False) -> int:
        if self.trust_warning:
            print(self.trust_warning, file=sys.stderr)
        if self.program is not None and not quiet:
            print(f"wrote {self.program}")
        for w in self.warnings:
            warn(w)
        if not quiet:
            print(self.summary)
        if self.error:
            error(self.error)
        return self.exit_code


@dataclass(frozen=True)
class _Planned:
    """The targets planned: ``planned`` every target's result (``ok`` and ``failed`` of
    them), ``poses`` / ``pose_of`` (by target id) the full poses when joint 4 or the tool is
    planned (else None), ``std`` each ``ok`` target's plan.csv std columns (``std_mm`` and
    its parts, :func:`vision_cal.plan.uncertainty.target_std`; ``std_mm`` NaN alone when
    unknown: the nominal model)."""

    planned: list
    ok: list
    failed: list
    poses: list | None
    pose_of: dict | None
    std: list


def plan(req: PlanRequest) -> PlanOutcome:
    """Plan ``req.targets`` with the model of ``req.calibration``; write the plan (and the
    trajectory, the robot program) together or not at all. Its exit code: 0, or 1 when no
    target could be planned."""
    prg, report = _check_outputs(req)
    robot = _robot_of(req)
    model, doc = load_calibration(req.calibration, which=req.model)
    warn = refuse_unreliable(doc, req.calibration, force=req.force)
    home_deg = _home_deg(req, doc, robot)
    ids, xy = read_targets(req.targets)
    if req.trajectory:  # a million targets: refused before they are planned
        try:
            check_length(len(ids))
        except VisionCalError as e:
            raise VisionCalError(e.reason, file=str(req.trajectory),
                                 field="--trajectory") from e
    p = _plan_targets(req, model, doc, robot, ids, xy)
    # the request against what the calibration was calibrated for, before anything is
    # written: a target outside is not planned (PLAN.failed.csv: why, and what covers it),
    # a whole request outside (the program's pen height) refused; with --force every one
    # written with the extrapolation stated
    outside = _outside_valid_for(req, doc, p, robot, model)
    whole, items = outside_per_item(outside)
    said = enforce_valid_for(outside if req.force else whole, file=str(req.calibration),
                             force=req.force, what=str(req.targets))
    if items and not req.force:
        p = _without(p, items)
    written_program = _write_outputs(req, model, robot, p, said, _flagged_targets(outside),
                                     home_deg, prg, report)
    return _outcome(req, doc, p, said, warn, written_program, report)


def _check_outputs(req: PlanRequest) -> tuple[Path | None, Path]:
    """Refuse outputs of another kind than they should be (a calibration.json, an image:
    issue 30) or one over another or over an input; return the program's path (None
    without ``--program``) and the failed targets' report's path."""
    output_file_of_kind(req.out, "csv", field="-o")
    if req.trajectory:
        output_file_of_kind(req.trajectory, "csv", field="--trajectory")
    prg = None
    if req.program:
        prg = program_path(req.program, Path(req.out).with_suffix(""))
        output_file_of_kind(prg, "csv" if req.program == "csv" else "text", field="--program")
    report = failed_report_path(req.out)
    distinct_outputs([("-o", req.out), ("-o (its failed targets)", report),
                      ("--trajectory", req.trajectory), ("--program", prg)],
                     _inputs(req))
    return prg, report


def _inputs(req: PlanRequest) -> list:
    return [("CALIBRATION.json", req.calibration), ("TARGETS.csv", req.targets),
            ("--robot", req.robot)]


def _robot_of(req: PlanRequest):
    """The robot file's description (None without ``--robot``), its program checked;
    ``--program`` without ``--robot`` refused."""
    if req.program and not req.robot:
        raise VisionCalError("--program needs --robot ROBOT.yaml (pen heights, speeds)",
                             field="--robot")
    robot = None
    if req.robot:
        robot = load_robot_file(req.robot)
        if req.program:
            check_program(req.program, robot)
    return robot


def _plan_targets(req: PlanRequest, model, doc: dict, robot, ids, xy) -> _Planned:
    """Every target planned within the joint limits (the robot file's, else those the run
    recorded), with joint 4 and the tool when the targets give an angle or the model has a
    tool (plan/orient.py), and the predicted std of those planned (calibrated model)."""
    limits = {} if robot is None else {"joint_limits_deg": robot.joint_limits_deg}
    if robot is None and doc.get("joint_limits_deg") is not None:   # recorded by the run
        limits = {"joint_limits_deg": tuple(tuple(float(v) for v in p)
                                            for p in doc["joint_limits_deg"])}
    theta = read_target_theta(req.targets)
    poses = pose_of = None
    if theta is not None or model.tool is not None:   # joint 4 and the tool (plan/orient.py)
        if robot is not None:
            limits["joint4_limits_deg"] = robot.joint4_limits_deg
        poses = plan_poses(model, ids, xy, theta, elbow=req.elbow,
                           approach=(*req.approach, req.approach4),
                           q4_deg=robot.j4_deg if robot is not None else 0.0, **limits)
        planned = [p.target for p in poses]
        pose_of = {p.target.id: p for p in poses}
    else:
        planned = plan_targets(model, ids, xy, elbow=req.elbow, approach=tuple(req.approach),
                               **limits)
    cov = load_covariance(doc, model, file=req.calibration) if req.model == "calibrated" \
        else None
    ok = [p for p in planned if p.status == "ok"]
    failed = [p for p in planned if p.status != "ok"]
    if poses is None:
        q_ok, a_ok = [p.q_deg for p in ok], [p.approach for p in ok]
    else:
        q_ok = [(*p.q_deg, pose_of[p.id].q4_deg) for p in ok]
        a_ok = [(*p.approach, pose_of[p.id].approach4) for p in ok]
    std = (target_std(model, cov, q_ok, a_ok, [p.target_mm for p in ok], doc).rows()
           if cov is not None and ok else [{"std_mm": float("nan")}] * len(ok))
    return _Planned(planned, ok, failed, poses, pose_of, std)


def _write_outputs(req: PlanRequest, model, robot, p: _Planned, said, flagged: dict,
                   home_deg, prg, report) -> Path | None:
    """Write the plan, the failed targets' report, the trajectory and the program, together
    or not at all (a program path that cannot be written, a trajectory too long, leave the
    earlier files as they were); return the program written (None: none)."""
    ok, poses, pose_of = p.ok, p.poses, p.pose_of
    written_program = None
    # one output set: an earlier run's plan, report, trajectory and program (of any
    # dialect) go to previous/plan-<name>/ first, whatever this run writes
    with replacing_files([("-o", req.out), ("-o (its failed targets)", report),
                          ("--trajectory", req.trajectory), ("--program", prg)],
                         command="plan", inputs=_inputs(req), quiet=req.quiet,
                         siblings=[program_path(k, Path(req.out).with_suffix(""))
                                   for k in PROGRAM_KINDS]), written_together():
        # the command file holds only what can be sent to the robot: no NaN, no failed row
        # (an unknown std, as with the nominal model, is left empty)
        write_plan(req.out, [dict(t.to_row() if poses is None else pose_of[t.id].to_row(),
                                   **{k: float(v) if math.isfinite(v) else ""
                                      for k, v in s.items()},
                                   **({"outside_valid_for": flagged.get(t.id, "")}
                                      if said else {}))
                              for t, s in zip(ok, p.std)])
        if p.failed:
            write_failed_targets(report, [(t.id, *t.target_mm, t.reason) for t in p.failed])
        if req.trajectory and ok:
            try:
                write_plan_trajectory(req.trajectory, ok, home_deg=home_deg)
            except VisionCalError as e:
                raise VisionCalError(e.reason, file=str(req.trajectory),
                                     field="--trajectory") from e
        if req.program and ok:  # no program of nothing (exit 1 in the outcome)
            marks = to_planned_marks(ok, overshoot_deg=robot.overshoot_deg, role="target")
            joint4, tool = None, None
            if poses is not None:   # joint 4 turns: its via point on the approach side
                joint4 = {t.target.id: (t.q4_deg, t.q4_deg - t.approach4 * robot.overshoot_deg)
                          for t in poses if t.target.status == "ok"}
                if model.tool is not None:
                    tool = controller_tool_mm(model.params, model.tool.tool_mm)
            points = program_points(marks, home_deg=home_deg,
                                    z2_deg=model.params.z2_deg, joint4=joint4)
            written_program = write_program(req.program, prg, points, robot,
                                 title=f"vision-cal compensated targets: {len(ok)} of "
                                       f"{len(p.planned)} targets of {req.targets}, "
                                       f"{req.model} model" + "".join(
                                           f"; EXTRAPOLATED: {w}" for w in said),
                                 tool_mm=tool)
    return written_program


def _without(p: _Planned, items: dict) -> _Planned:
    """``p`` with the targets outside ``valid_for`` (id -> its lines) moved from ``ok`` to
    ``failed``, each with why and what would cover it."""
    out = [replace(t, status="outside valid_for", reason=" | ".join(items[t.id]))
           for t in p.ok if t.id in items]
    keep = [(t, s) for t, s in zip(p.ok, p.std) if t.id not in items]
    return _Planned([next((o for o in out if o.id == t.id), t) for t in p.planned],
                    [t for t, _ in keep], p.failed + out, p.poses, p.pose_of,
                    [s for _, s in keep])


def _outcome(req: PlanRequest, doc: dict, p: _Planned, said, warn, written_program,
             report) -> PlanOutcome:
    """What the planning says: the failed targets, the targets on the print, the
    extrapolations; the error when nothing could be planned; partial when some were not."""
    ok, failed, planned = p.ok, p.failed, p.planned
    warnings = []
    if failed and ok:  # when none is planned, the error below says it once
        warnings.append(f"{req.targets}: {summarise_failures(failed)}; all in {report}")
    warnings += _targets_on_print(req, doc, ok) + list(said)
    return PlanOutcome(
        f"planned {len(planned) - len(failed)} of {len(planned)} targets with the "
        f"{req.model} model -> {req.out}", warn, written_program,
        tuple(warnings),
        None if ok else (f"{req.targets}: nothing could be planned with the {req.model} "
                         f"model of {req.calibration}: {summarise_failures(failed)}; "
                         f"all in {report}"), partial=bool(failed) and bool(ok))


def _targets_on_print(req, doc: dict, ok) -> list[str]:
    """The warning (none or one line) naming the planned targets that lie on the sheet's
    printed ink (calibration.json ``printed_content``) and what it costs."""
    content = doc.get("printed_content") or []
    if not content or not ok:
        return []
    on = targets_on_print(content, [p.id for p in ok], [p.target_mm for p in ok], 1.0)
    if not on:
        return []
    head = "; ".join(f"{tid} ({', '.join(labels)})" for tid, labels in on[:3])
    more = f" and {len(on) - 3} more" if len(on) > 3 else ""
    return [f"{req.targets}: {len(on)} target(s) on the sheet's printed ink: {head}{more}: a "
            "pen mark there is measured against the print (0.01-0.02 mm less certain) or, "
            "where it cannot be separated, left out as unreliable; move the target by a few "
            "millimetres onto plain paper to check it"]


def _outside_valid_for(req, doc: dict, p: _Planned, robot, model) -> list:
    """What of the planned targets lies outside calibration.json ``valid_for``
    (:func:`vision_cal.dataset.valid_for.check`): joints beyond the range the marks covered
    where the model's std grows beyond what keeps its stated error, an approach side never seen,
    joint 4 turned with a tool never identified, a program drawing at another height. The
    nominal model (``--model nominal``) is not a calibration: nothing to check."""
    ok, pose_of = p.ok, p.pose_of
    if req.model != "calibrated" or not ok:
        return []
    ids = [t.id for t in ok]
    approach = [tuple(t.approach) + ((pose_of[t.id].approach4,) if pose_of else ())
                for t in ok]
    q4 = [pose_of[t.id].q4_deg for t in ok] if pose_of else None
    pen = robot.pen_down_mm if (robot is not None and req.program) else None
    return check_valid_for(valid_for_of(doc, file=str(req.calibration)),
                           cal=str(req.calibration), ids=ids,
                           joints_deg=[t.q_deg for t in ok], approach=approach,
                           joint4_deg=q4, pen_down_mm=pen,
                           # the calibration's part: what the covered range's limit is of
                           std_mm=[r["std_calibration_mm"] for r in p.std],
                           std_limit_mm=std_limit_mm(model, doc, file=str(req.calibration)),
                           beyond_deg=beyond_deg(doc))


def _flagged_targets(outside) -> dict:
    """target id -> the fields of valid_for it lies outside (plan.csv ``outside_valid_for``)."""
    out: dict = {}
    for o in outside:
        for tid in o.ids:
            out[tid] = (out.get(tid, "") + " " + o.field).strip()
    return out


def summarise_failures(failed, *, first: int = 3) -> str:
    """One line for any number of failed targets: counts per kind of reason, the first few
    (those outside ``valid_for`` by name only: why, and what would cover each, are in the
    failed targets' report)."""
    kinds: dict[str, int] = {}
    for p in failed:
        k = ("outside valid_for" if p.status == "outside valid_for" else
             next((k for k in ("out of reach", "singularity", "outside its limits",
                               "could not be inverted") if k in p.reason), "other"))
        kinds[k] = kinds.get(k, 0) + 1
    counts = ", ".join(f"{n} {k}" for k, n in sorted(kinds.items(), key=lambda kv: -kv[1]))
    plain = [p for p in failed if p.status != "outside valid_for"]
    beyond = [p.id for p in failed if p.status == "outside valid_for"]
    parts = [f"target {p.id}: {p.reason}" for p in plain[:first]]
    if len(plain) > first:
        parts[-1] += f" (and {len(plain) - first} more)"
    if beyond:
        names = ", ".join(beyond[:first]) + (f" and {len(beyond) - first} more"
                                             if len(beyond) > first else "")
        parts.append(f"outside what the calibration was calibrated for (valid_for): {names}, "
                     "each with why and what would cover it in the report (--force plans "
                     "them, the extrapolation stated)")
    return f"{len(failed)} target(s) not planned ({counts}): {'; '.join(parts)}"


def _home_deg(req, doc: dict, robot) -> tuple[float, float]:
    """Where the planned motion starts: ``--home``, else the robot file's ``home_deg``, else
    calibration.json's ``home_deg`` (the session's), else (0, 0)."""
    if req.home is not None:
        home, where, file = req.home, "--home", None
        lims = JOINT_LIMITS_DEG if robot is None else robot.joint_limits_deg
        of = "the default joint limits" if robot is None else f"joint_limits_deg of {req.robot}"
        for j in range(2):
            if not (math.isfinite(home[j]) and lims[j][0] <= home[j] <= lims[j][1]):
                raise VisionCalError(f"joint {j + 1} at {home[j]:g} deg is outside {of} "
                                     f"{list(lims[j])}", field="--home")
    elif robot is not None:
        return tuple(robot.nominal.home_deg)
    elif "home_deg" in doc:
        home, where, file = doc["home_deg"], "home_deg", req.calibration
    else:
        return (0.0, 0.0)
    if (not isinstance(home, (list, tuple)) or len(home) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                       and math.isfinite(v) for v in home)):
        raise VisionCalError(f"expected two finite joint angles in degrees, got {home!r}",
                             file=file, field=where)
    return (float(home[0]), float(home[1]))
