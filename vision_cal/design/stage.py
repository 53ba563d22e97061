"""One design stage: robot file + sheet.json (+ pilot calibration) -> a planned dataset.

``design_stage`` writes into ``out_dir``::

    session.json      sheet (sheet.json verbatim), robot, pen, marks (joints_deg, approach,
                      role) and no images yet: the dataset skeleton the photos go into;
                      added field ``design`` (stage, how it was designed)
    trajectory.csv    the joint-space reference (0.016 s cubic segments through the
                      overshoot via points; vision_cal.plan.trajectory)
    program.prg       the robot program (--program spel), or program_points.csv (csv);
                      none, with one warning, when the robot file has no pen heights
    preview.png       the sheet, the robot at its guessed base with both links at joint
                      zero and at a few planned marks, the marks (design/preview.py)

Without a pilot calibration it designs the pilot (:mod:`vision_cal.design.pilot`); with
one, the informative plan (:func:`vision_cal.plan.calibration_plan.informative_plan`)
placed with the pilot's model, with :data:`DESIGN_REPEATS` of its marks drawn twice.
Everything is computed before anything is written, and each file is written atomically.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from vision_cal.dataset.calibration import load_calibration
from vision_cal.dataset.covariance import load_covariance
from vision_cal.dataset.fields import FieldReader
from vision_cal.dataset.io import atomic_write_bytes, atomic_write_json
from vision_cal.dataset.photos import list_photos
from vision_cal.dataset.robot import load_robot_file
from vision_cal.dataset.session import (NominalRobot, SheetMarker, load_sheet_file,
                                        resolve_approach, sheet_file_block)
from vision_cal.dataset.valid_for import check as check_valid_for
from vision_cal.dataset.valid_for import of as valid_for_of
from vision_cal.plan.extrapolation import beyond_deg, std_at_mm, std_limit_mm
from vision_cal.dataset.sheet_identity import check_same_sheet
from vision_cal.design.iso9283 import PITCH_MM, iso_marks
from vision_cal.design.joint4 import circle_triples, joint4_vias, turn_joint4
from vision_cal.design.pilot import design_pilot
from vision_cal.design.preview import REACH_WARN, preview_png, reach_fraction
from vision_cal.errors import VisionCalError
from vision_cal.model.kinematics import ScaraParams, forward
from vision_cal.measure.printed import printed_reference
from vision_cal.plan.calibration_plan import informative_plan
from vision_cal.plan.trajectory import plan_trajectory, write_trajectory_csv
from vision_cal.plan.uncertainty import predicted_std_mm
from vision_cal.program import check_program, program_path, program_points, write_program

FORMAT = "vision-cal/1"
#: calibration marks the informative plan draws a second time (``repeat_of``), so the
#: verdict's noise floor uses the robot's repeatability measured on the day: 8 pairs know
#: the floor within about 18 % (1 std), inside the gate's 25 % tolerance (docs/plans.md)
DESIGN_REPEATS = 8


@dataclass(frozen=True)
class DesignResult:
    stage: str                 # "pilot" | "informative"
    session_path: Path
    trajectory_path: Path
    program_path: Path | None
    n_marks: int
    duration_s: float
    info: dict


def pilot_safety_mm(model, cov, sheet, *, k_sigma: float = 6.0, floor_mm: float = 5.0,
                    rng=None) -> float:
    """Safety margin (mm) for marks placed with a pilot model: ``floor_mm`` plus
    ``k_sigma`` times the largest predicted per-axis std over poses landing on the paper."""
    rng = np.random.default_rng(0 if rng is None else rng)
    q = rng.uniform([-170, -150], [170, 150], size=(4000, 2))
    xy = model.predict(q)
    x0, y0, x1, y1 = sheet.extent_mm
    on = (xy[:, 0] > x0) & (xy[:, 0] < x1) & (xy[:, 1] > y0) & (xy[:, 1] < y1)
    if not on.any():
        return floor_mm
    s = predicted_std_mm(model, cov, q[on], np.ones((int(on.sum()), 2)))
    return float(floor_mm + k_sigma * np.nanmax(s))


def drawable_sheet(sheet, sheet_raw: dict, *, file: str | None = None):
    """The sheet to place marks on: the paper, or only its ``printed.drawable_mm`` box
    ``[x0, y0, x1, y1]`` when the generator says where pen marks may go (clear of scale
    bars, labels and the title block), with the same markers."""
    printed = sheet_raw.get("printed")
    box = printed.get("drawable_mm") if isinstance(printed, dict) else None
    if box is None:
        return sheet
    x0, y0, x1, y1 = FieldReader(file).vector(box, "printed.drawable_mm", 4)
    px0, py0, px1, py1 = sheet.extent_mm
    if not (px0 <= x0 < x1 <= px1 and py0 <= y0 < y1 <= py1):
        raise VisionCalError(f"expected [x0, y0, x1, y1] inside the paper {list(sheet.extent_mm)}"
                             f", got {box!r}", file=file, field="printed.drawable_mm")
    return replace(sheet, size_mm=(x1 - x0, y1 - y0), bottom_left_mm=(x0, y0))


def with_printed_content(sheet):
    """The sheet with what its own print has inside the drawable area (the axes, their
    arrows and letters, "origin (0, 0)": :mod:`vision_cal.measure.printed`) as obstacles,
    kept clear of as the markers are: a pen mark on printed ink is measured less well.
    A sheet whose print is not described is returned as it is. Used for the informative
    plan (placed with the pilot's model); the pilot's marks may land anywhere within the
    placement tolerance, so print under them is left to the measurement."""
    ref = printed_reference(sheet)
    if ref is None:
        return sheet
    x0, y0, x1, y1 = sheet.extent_mm
    extra = []
    for k, it in enumerate(ref.items):
        a, b, c, d = it.box_mm
        if c < x0 or a > x1 or d < y0 or b > y1:
            continue
        extra.append(SheetMarker(-10000 - k, np.array([[a, d], [c, d], [c, b], [a, b]])))
    return replace(sheet, markers=tuple(sheet.markers) + tuple(extra))


def with_drawable_bands(sheet, paper):
    """The sheet with the paper outside its drawable box as obstacles: ``sheet`` is
    :func:`drawable_sheet`'s, ``paper`` the whole paper's. Its ``extent_mm`` still spans
    the markers (they are printed outside the drawable box), so a planner that keeps to
    the extent and clear of markers would put marks on the scale bars, labels and title;
    the four bands between the paper edge and the drawable box become rectangles it keeps
    clear of, like markers."""
    if sheet.bottom_left_mm is None or sheet is paper:
        return sheet
    px0, py0, px1, py1 = paper.extent_mm
    x0, y0 = sheet.bottom_left_mm
    x1, y1 = x0 + sheet.size_mm[0], y0 + sheet.size_mm[1]
    bands = [(px0, py0, px1, y0), (px0, y1, px1, py1), (px0, y0, x0, y1), (x1, y0, px1, y1)]
    extra = [SheetMarker(-1000 - k, np.array([[a, d], [c, d], [c, b], [a, b]], float))
             for k, (a, b, c, d) in enumerate(bands) if c > a and d > b]
    return replace(sheet, markers=tuple(sheet.markers) + tuple(extra))


def _measured_marks(cal_doc: dict) -> list[list[float]]:
    """The measured positions [x, y] (mm) of a calibration's marks."""
    out = []
    for m in (cal_doc.get("marks") or {}).values():
        xy = m.get("measured_mm") if isinstance(m, dict) else None
        if isinstance(xy, list) and len(xy) == 2:
            out.append([float(xy[0]), float(xy[1])])
    return out


def with_pilot_marks(sheet, cal_doc: dict, diameter_mm: float):
    """The sheet with the pilot's measured marks as obstacles (small squares), so that
    the informative plan drawn on the same sheet keeps clear of them."""
    extra = []
    for k, m in enumerate((cal_doc.get("marks") or {}).values()):
        xy = m.get("measured_mm") if isinstance(m, dict) else None
        if not (isinstance(xy, list) and len(xy) == 2):
            continue
        x, y = float(xy[0]), float(xy[1])
        h = diameter_mm / 2
        extra.append(SheetMarker(-1 - k, np.array([[x - h, y + h], [x + h, y + h],
                                                   [x + h, y - h], [x - h, y - h]])))
    return replace(sheet, markers=tuple(sheet.markers) + tuple(extra))


def design_stage(robot_path, sheet_path, out_dir, *, pilot=None, program: str | None = "spel",
                 n_calibration: int = 30, n_validation: int = 8, safety_mm: float | None = None,
                 seed: int = 0, stage: str | None = None,
                 iso9283_cycles: int = 0) -> DesignResult:
    """The stage's files in ``out_dir`` (see the module docstring): the pilot without
    ``pilot``, else the informative plan placed with the pilot calibration's model (a
    check of it when ``stage == "verify"``, with ``iso9283_cycles`` of ISO 9283's points)."""
    robot = load_robot_file(robot_path)
    sheet = load_sheet_file(sheet_path)
    sheet_raw = sheet_file_block(sheet_path)[0]
    out = Path(out_dir)
    _check_out_dir(out)
    warnings = []
    if program is not None and (robot.pen_up_mm is None or robot.pen_down_mm is None):
        # the plan and the trajectory do not need them: write those, skip only the program
        warnings.append(f"{robot_path}: pen_up_mm, pen_down_mm: missing, so no robot program "
                        "was written (session.json and trajectory.csv were); add both heights "
                        "(joint 3, mm; docs/robot-file.md) and run design again")
        program = None
    if program is not None:   # what the dialect cannot express, before anything is written
        check_program(program, robot, program_path(program, out / "program").stem)
    paper = sheet
    sheet = drawable_sheet(sheet, sheet_raw, file=str(sheet_path))
    if pilot is not None:   # the pilot lands anywhere within the tolerance: measured over print
        sheet = with_printed_content(sheet)
    nominal = robot.nominal
    reach, reach_note = _reach(robot, sheet)
    if reach < REACH_WARN:
        warnings.append(f"{robot_path}: {reach_note}")
    joint4 = None   # mark id -> j4_deg when the plan turns joint 4
    if pilot is None:
        marks, plan_robot, info, title = _pilot_plan(robot, sheet, robot_path, reach,
                                                     reach_note)
    else:
        doc, sheet, marks, plan_robot, info, title, joint4 = _informative_plan(
            robot, sheet, paper, sheet_raw, sheet_path, pilot, n_calibration=n_calibration,
            n_validation=n_validation, safety_mm=safety_mm, seed=seed, stage=stage,
            iso9283_cycles=iso9283_cycles)
        # the plan against what the calibration it was placed with saw
        _against_valid_for(doc, pilot, marks, nominal.home_deg, joint4, stage, info, warnings)
    traj = plan_trajectory(marks, home_deg=nominal.home_deg, vmax_deg_s=robot.speed_limits_deg_s,
                           amax_deg_s2=robot.accel_limits_deg_s2,
                           dwell_s=robot.program.settle_s)
    info["nominal_robot"] = nominal.to_json()   # the robot file: every "nominal" (dataset/nominal)
    if robot.pen_down_mm is not None:   # the height the marks are drawn at (valid_for)
        info["pen_down_mm"] = robot.pen_down_mm
    if warnings:
        info["warnings"] = warnings
    info["trajectory_s"] = traj.duration_s
    session = _session_doc(robot, sheet_raw, plan_robot, marks, joint4, info)
    points = program_points(marks, home_deg=nominal.home_deg, z2_deg=plan_robot.joint_zero_deg[1],
                            joint4=None if joint4 is None else joint4_vias(
                                marks, joint4, start_deg=robot.j4_deg,
                                overshoot_deg=robot.overshoot_deg))
    preview = preview_png(_params(plan_robot), sheet, marks, paper=paper,
                          title=f"{info['stage']} plan: {len(marks)} marks, robot "
                                f"{robot.name} ({100 * reach:.0f} % of the paper in reach)")
    info["reach_fraction"] = reach
    # everything is computed: now write
    session_path = atomic_write_json(out / "session.json", session)

    atomic_write_bytes(out / "preview.png", preview)
    traj_path = write_trajectory_csv(out / "trajectory.csv", traj)
    prog_path = None
    if program is not None:
        prog_path = write_program(program, program_path(program, out / "program"), points, robot,
                                  title=title)
    return DesignResult(info["stage"], session_path, traj_path, prog_path, len(marks),
                        traj.duration_s, info)


def _check_out_dir(out: Path) -> None:
    """Refuses an ``--out`` that is a file, or a folder holding photos (of another plan)."""
    if out.exists() and not out.is_dir():
        raise VisionCalError("exists and is not a folder", file=str(out))
    if out.is_dir():
        photos = list_photos(out)
        if photos:
            raise VisionCalError(f"holds photos ({photos[0]}, ...) of a plan: a new plan would "
                                 "not match them; choose another --out", file=str(out))


def _params(r) -> ScaraParams:
    """The kinematic parameters of a robot block (``NominalRobot``)."""
    return ScaraParams(r.L1_mm, r.L2_mm, r.joint_zero_deg[0], r.joint_zero_deg[1],
                       r.base_mm[0], r.base_mm[1])


def _reach(robot, sheet) -> tuple[float, str]:
    """The fraction of the drawable paper the robot file's nominal robot reaches within
    its joint limits, and the sentence a low one is explained with."""
    nominal = robot.nominal
    reach = reach_fraction(_params(nominal), sheet, joint_limits_deg=robot.joint_limits_deg,
                           elbows=robot.elbows)
    reach_note = (f"the robot file's base_mm {list(nominal.base_mm)} and joint_zero_deg "
                  f"{list(nominal.joint_zero_deg)} put only {100 * reach:.0f} % of the "
                  "drawable paper within the arm's reach and joint limits: check base_mm (sheet "
                  "frame, mm) and z1 (it includes the robot's rotation to the sheet; "
                  "docs/robot-file.md)")
    return reach, reach_note


def _pilot_plan(robot, sheet, robot_path, reach: float, reach_note: str):
    """The pilot's ``(marks, plan_robot, info, title)``; a refusal names the robot file and,
    when little of the paper is in reach, says so."""
    try:
        d = design_pilot(robot, sheet)
    except VisionCalError as e:
        why = f"{e.reason}; {reach_note}" if reach < REACH_WARN else e.reason
        raise VisionCalError(why, file=e.file or str(robot_path), field=e.field) from e
    marks = list(d.marks)
    title = (f"vision-cal pilot: {len(marks)} marks of the seed paper's pattern, kept on "
             "free paper for every placement within the robot file's tolerance")
    return marks, robot.nominal, d.to_json(), title


def _informative_plan(robot, sheet, paper, sheet_raw: dict, sheet_path, pilot, *,
                      n_calibration: int, n_validation: int, safety_mm: float | None,
                      seed: int, stage: str | None, iso9283_cycles: int):
    """The informative plan (or, ``stage == "verify"``, the check) placed with the pilot
    calibration's model: ``(doc, sheet, marks, plan_robot, info, title, joint4)``, with
    ``doc`` the calibration, ``sheet`` with the obstacles the marks kept clear of, and
    ``joint4`` mark id -> j4_deg when the plan turns joint 4 (else None)."""
    nominal = robot.nominal
    model, doc = load_calibration(pilot)

    check_same_sheet(doc, sheet_raw, file=str(pilot), sheet_file=str(sheet_path))
    cov = load_covariance(doc, model, file=str(pilot))
    if safety_mm is None:
        safety_mm = pilot_safety_mm(model, cov, sheet)
    sheet = with_pilot_marks(with_drawable_bands(sheet, paper), doc, robot.mark_diameter_mm)
    p = model.params
    plan_robot = NominalRobot(p.L1_mm, p.L2_mm, p.joint_zero_deg, p.base_mm, nominal.home_deg)
    iso_extra, iso = [], None
    if stage == "verify" and iso9283_cycles:
        sheet, iso_extra, iso = _with_iso9283(model, sheet, robot, iso9283_cycles)
    try:
        marks = informative_plan(
            p, sheet, n_calibration=n_calibration, n_validation=n_validation,
            pen_diameter_mm=robot.mark_diameter_mm, joint_limits_deg=robot.joint_limits_deg,
            rng=seed, safety_mm=safety_mm, overshoot_deg=robot.overshoot_deg,
            home_deg=nominal.home_deg, elbows=robot.elbows,
            speed_deg_s=robot.speed_limits_deg_s,
            n_repeats=0 if stage == "verify" else DESIGN_REPEATS)
    except VisionCalError as e:
        raise VisionCalError(e.reason, file=str(sheet_path), field=e.field) from e
    info = {"stage": "informative", "pilot_calibration": str(pilot), "safety_mm": safety_mm,
            "n_calibration": n_calibration, "n_validation": n_validation, "seed": seed,
            "n_repeats": sum(m.repeat_of is not None for m in marks),
            # the marks already on this sheet (the pilot's, as measured): known, not this
            # plan's (the measurement names them so)
            "earlier_marks_mm": _measured_marks(doc)}
    joint4 = None
    if nominal.tool_mm is not None and any(nominal.tool_mm):   # an off-axis tool (#21)
        marks, joint4 = _turned_joint4(marks, p, robot, sheet, safety_mm, seed, stage, info)
    title = (f"vision-cal calibration plan: {n_calibration} calibration + {n_validation} "
             "validation marks, both elbows, both approach sides per joint")
    if stage == "verify":   # vision-cal verify: a short check of a calibration
        info.update(stage="verify", calibration=str(pilot))
        if iso_extra:
            marks = list(marks) + list(iso_extra)
            info["iso9283"] = {"cycles": iso9283_cycles, "marks": iso}
        title = (f"vision-cal check of {Path(pilot).name}: {n_calibration} marks, both "
                 "elbows, both approach sides (then: vision-cal verify)")
    return doc, sheet, marks, plan_robot, info, title, joint4


def _with_iso9283(model, sheet, robot, cycles: int):
    """ISO 9283's points for a check, placed first: ``(sheet, marks, iso)`` with the sheet
    keeping the check's other marks clear of their patches."""
    bl, sz = sheet.bottom_left_mm, sheet.size_mm
    box = (bl[0], bl[1], bl[0] + sz[0], bl[1] + sz[1]) if bl is not None \
        else sheet.extent_mm
    iso_extra, iso = iso_marks(model, box, cycles, elbow=robot.elbows[0],
                               overshoot_deg=robot.overshoot_deg,
                               joint_limits_deg=robot.joint_limits_deg)
    h = PITCH_MM * (np.ceil(np.sqrt(cycles)) + 1) / 2
    centres = sorted({tuple(v["point_mm"]) for v in iso.values()})
    patches = [SheetMarker(-2000 - k, np.array([[x - h, y + h], [x + h, y + h],
                                                [x + h, y - h], [x - h, y - h]]))
               for k, (x, y) in enumerate(centres)]
    return replace(sheet, markers=tuple(sheet.markers) + tuple(patches)), iso_extra, iso


def _turned_joint4(marks, p, robot, sheet, safety_mm: float, seed: int, stage, info: dict):
    """With an off-axis tool: the marks with joint 4 turned, and (not for a check) the seed
    paper's joint-4 circles (triples at one pose, both elbows and sides) added;
    ``(marks, joint4)`` with joint4 mark id -> j4_deg, the triples and turns into ``info``."""
    tool = robot.nominal.tool_mm
    points = forward(p, [m.joints_deg for m in marks])
    marks, joint4 = turn_joint4(marks, p, tool, folded_j4_deg=robot.j4_deg,
                                overshoot_deg=robot.overshoot_deg)
    if stage != "verify":
        triples, t4 = circle_triples(
            p, tool, sheet, avoid_xy=points, folded_j4_deg=robot.j4_deg,
            clearance_mm=robot.mark_diameter_mm / 2 + 3.0 + safety_mm,
            joint_limits_deg=robot.joint_limits_deg,
            joint4_limits_deg=robot.joint4_limits_deg,
            overshoot_deg=robot.overshoot_deg, elbows=robot.elbows, rng=seed)
        marks, joint4 = list(marks) + triples, {**joint4, **t4}
        info["joint4_triples"] = [[m.id for m in triples[i:i + 3]]
                                  for i in range(0, len(triples), 3)]
    info["joint4_turns"] = sorted(set(joint4.values()))
    return marks, joint4


def _session_doc(robot, sheet_raw: dict, plan_robot, marks, joint4, info: dict) -> dict:
    """session.json of the plan: the sheet verbatim, the robot it was placed with (with
    the robot file's joint limits, which travel into calibration.json), the pen, the marks
    (with j4_deg when joint 4 turns) and ``design`` = ``info`` (the same dict)."""
    session = {"format": FORMAT, "sheet": sheet_raw, "robot": plan_robot.to_json(),
               "pen": {"mark_diameter_mm": robot.mark_diameter_mm},
               "marks": [dict(m.to_json(), **({"j4_deg": joint4[m.id]} if joint4 else {}))
                         for m in marks], "design": info}
    session["robot"]["joint_limits_deg"] = [[float(v) for v in p] for p in robot.joint_limits_deg]
    return session


def _against_valid_for(doc: dict, cal, marks, home_deg, joint4, stage, info: dict,
                       warnings: list) -> None:
    """The designed marks against the ``valid_for`` of the calibration they were placed
    with (:mod:`vision_cal.dataset.valid_for`). An informative plan goes beyond its pilot's
    by design (both approach sides, the whole sheet, joint 4 turned): the pilot's model is
    its starting model, its safety margin covers the extrapolation, and session.json
    ``design.beyond_valid_for`` says where. A check (``--verify``) beyond its calibration
    compares with an extrapolation: a warning (``verify`` refuses it without --force)."""
    ids = [m.id for m in marks]
    q = [list(m.joints_deg) for m in marks]
    a = resolve_approach(marks, home_deg).astype(int).tolist()
    model = load_calibration(cal)[0]   # as verify will judge them: the std rule too
    outside = check_valid_for(valid_for_of(doc, file=str(cal)), cal=str(cal), ids=ids,
                              joints_deg=q,
                              approach=a, joint4_deg=None if not joint4 else
                              [joint4.get(i) for i in ids],
                              std_mm=std_at_mm(model, doc, q, a, file=str(cal)),
                              std_limit_mm=std_limit_mm(model, doc, file=str(cal)),
                              beyond_deg=beyond_deg(doc))
    if not outside:
        return
    info["beyond_valid_for"] = [o.to_json() for o in outside]
    if stage == "verify":
        warnings.append(f"{cal}: the check goes beyond what it calibrated: "
                        + "; ".join(o.reason for o in outside)
                        + " (vision-cal verify refuses such marks without --force)")
