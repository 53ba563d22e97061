"""The calibration of one run: a fit's blocks (:class:`~vision_cal.estimate.fit.Fitted`), the
measurement and the session made into the one
:class:`~vision_cal.dataset.calibration_result.CalibrationResult` (:func:`document`):
per-photo checks, the model the OLP had, the lens and the sheet's height the photos found,
every mark with its residuals, the targets, the still cameras, the paper's scale, what it
is valid for, and the verdict judged on all of it (:mod:`vision_cal.estimate.verdict`)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.dataset.io import read_json
from vision_cal.dataset.nominal import nominal_blocks
from vision_cal.dataset.session import Session
from vision_cal.dataset.sheet_identity import sheet_identity
from vision_cal.dataset.valid_for import build as valid_for_block
from vision_cal.estimate.fit import Fitted
from vision_cal.estimate.marks import MarkData
from vision_cal.estimate.paper_scale import paper_scale_block
from vision_cal.estimate.photos import per_photo_offsets
from vision_cal.estimate.report_data import with_report_data
from vision_cal.estimate.verdict import judge
from vision_cal.measure.printed import printed_content_json
from vision_cal.measure.types import Measurement
from vision_cal.model.rms import rms_2d


def document(session: Session, data: MarkData, missing: list[str],
             measurement: Measurement | None, fitted: Fitted, *, method: str,
             config: EstimatorConfig = DEFAULT, truth: bool = False,
             bars_mm=None, cameras=None) -> CalibrationResult:
    """The one :class:`CalibrationResult` of a run.

        result = document(session, data, missing, measurement, fitted, method="lsq")

    The fit's blocks, per-photo checks, the
    model the OLP had, the lens and the sheet height found by measurement, every mark with
    its residuals, images, targets, still cameras, the paper's scale (``bars_mm``: the
    printed bars as measured, over the sheet's), and the verdict judged on all of it.
    ``cameras``: (calibration.json ``cameras``, the notes about them) of the still cameras
    (:func:`vision_cal.camera.fixed.cameras_json`, from ``fitted``'s model), or None.
    Returned as written (:meth:`CalibrationResult.as_written`: what is read back)."""
    fit = fitted.result
    effects, diagnosis, notes = _measured(data, measurement, fitted, config)
    marks, unreliable_notes = _marks_json(session, data, measurement, fitted)
    if measurement is not None:
        notes += unreliable_notes
    limits = session.robot.joint_limits_deg
    printer = printer_scale(session.sheet, effects, fit.params, bars_mm=bars_mm)
    paper = paper_scale_block(session.sheet, fit.params, fit.std, printer, config)
    cameras, camera_notes = cameras or ([], [])
    if camera_notes:
        notes = list(notes or []) + camera_notes
    result = replace(
        fit, method=method, config=config.to_json(), effects=tuple(effects),
        diagnosis=diagnosis, notes=None if notes is None else tuple(notes),
        **nominal_blocks(session.raw, session.robot.params.to_json()),  # the robot file
        home_deg=tuple(float(v) for v in session.robot.home_deg),  # added: where plans start
        printed_content=printed_content_json(session.sheet) or None,  # added: for plan
        joint_limits_deg=(None if limits is None  # added: plan, export
                          else [[float(v) for v in p] for p in limits]),
        noise_floor_mm=(None if data.sigma_mm is None
                        else float(np.sqrt(2 * np.mean(data.sigma_mm**2)))),
        marks=marks, missing_marks=tuple(missing) or None,
        images=tuple(measurement.images_json()) if measurement else (),
        targets=tuple(_target_errors(session, data)) or None,
        printer_scale=printer,
        cameras=cameras or None,   # added: still cameras (vision_cal/camera/fixed.py)
        sheet=sheet_identity(session.raw.get("sheet")),  # which printed sheet: design --pilot
        # added (#28): the print's deviation from its layout and its limit on the marks;
        # (#37) the fit replicated by two halves of its marks; the paper's scale
        extra={**({"print": measurement.print_summary}
                  if measurement is not None and measurement.print_summary is not None
                  else {}), **fit.extra,
               **({} if paper is None else {"paper_scale": paper})})
    if truth:
        result = replace(result, truth_comparison=compare_truth(session.root / "truth.json",
                                                                result))
    design = session.raw.get("design") if isinstance(session.raw, dict) else None
    pen = (design or {}).get("pen_down_mm") if isinstance(design, dict) else None
    result = replace(result, valid_for=valid_for_block(
        result, pen_down_mm=pen if isinstance(pen, (int, float)) else None))
    # what the report draws: it reads only the files
    return with_report_data(_judged(result, session), session).as_written()


def _measured(data: MarkData, measurement: Measurement | None, fitted: Fitted,
              config: EstimatorConfig) -> tuple[list, dict | None, list | None]:
    """(effects, diagnosis, notes): the fit's, with what the photos add: per-photo offsets
    (:func:`vision_cal.estimate.photos.per_photo_offsets`), the lens found, the sheet's
    height (claimed or why not). Notes are a list when there is a measurement."""
    fit = fitted.result
    effects, diagnosis = list(fit.effects or ()), fit.diagnosis
    notes = None if fit.notes is None else list(fit.notes)
    if measurement is None:
        return effects, diagnosis, notes
    notes = list(notes or [])
    if fitted.diagnosis is not None:
        photos = per_photo_offsets(measurement, fitted.diagnosis.final_fit.model,
                                   dict(zip(data.ids, data.q_model)),
                                   dict(zip(data.ids, data.approach_model)),
                                   config=config.per_photo_offsets)
        diagnosis = {**diagnosis, "per_photo_offsets": photos}
        flagged = [p["file"] for p in photos if p["flagged"]]
        if flagged:
            notes.append("photos whose marks are shifted together beyond the noise "
                         "(a bad sheet mapping?): " + ", ".join(flagged))
    if measurement.lens is not None and measurement.lens.kept:
        effects.insert(0, measurement.lens.to_effect_json())
    if measurement.height_map is not None:
        hm = measurement.height_map
        if hm.claimed:
            effects.append(hm.to_effect_json())
        elif hm.not_claimed:
            notes.append(f"sheet_height not claimed: {hm.not_claimed}")
        diagnosis = {**(diagnosis or {}), "sheet_height": hm.to_json()}
    return effects, diagnosis, notes


def _judged(result: CalibrationResult, session: Session) -> CalibrationResult:
    """The run's verdict (one owner: :mod:`vision_cal.estimate.verdict`); a residual beyond
    the noise floor is ``unexplained`` with its ratio unless an effect entry already says
    what is left."""
    v = judge(result, repeatability_mm=session.robot.repeatability_mm,
              stage=session.design_stage)
    effects = [dict(e) for e in result.effects]
    f = v.floor
    if f is not None and f["beyond"]:
        ex = next((e for e in effects if e["name"] in ("unexplained", "drift")), None)
        line = v.floor_line
        if ex is None:
            effects.append({"name": "unexplained", "seen": [line],
                            "residual_over_floor": f["residual_over_floor"]})
        else:
            ex["residual_over_floor"] = f["residual_over_floor"]
            if ex["name"] == "unexplained":
                ex["seen"] = list(ex.get("seen", [])) + [line]
    return replace(result, effects=tuple(effects), verdict=v.to_json())


def _marks_json(session: Session, data: MarkData, measurement: Measurement | None,
                fitted: Fitted) -> tuple[dict, list[str]]:
    """calibration.json's ``marks`` (every fitted mark with its residuals, then the marks
    found but not trusted) and the notes about the latter."""
    marks = {}
    repeat_of = {m.id: m.repeat_of for m in session.marks if m.repeat_of is not None}
    for i, mid in enumerate(data.ids):
        entry = {"measured_mm": data.xy_mm[i].tolist(),
                 **({"j4_deg": float(data.joint4[i, 0])} if data.joint4 is not None else {}),
                 "residual_mm": np.asarray(fitted.residual_all[mid]).tolist(),
                 "residual_base_mm": np.asarray(fitted.residual_base[mid]).tolist(),
                 "role": data.roles[i], "joints_deg": data.q_deg[i].tolist(),
                 "approach": data.approach[i].astype(int).tolist()}
        if data.sigma_mm is not None:
            entry["sigma_mm"] = float(data.sigma_mm[i])
        if mid in repeat_of:   # added: a return to another mark's pose (repeatability)
            entry["repeat_of"] = repeat_of[mid]
        if measurement is not None and mid in measurement.marks:  # added field
            entry["n_photos"] = int(measurement.marks[mid].n_photos)
            entry.update(measurement.mark_json(mid))
        marks[mid] = entry
    if measurement is None:
        return marks, []
    return marks, _unreliable_marks(marks, session, measurement)


def _unreliable_marks(marks: dict, session: Session, measurement: Measurement) -> list[str]:
    """Marks found but not trusted (docs/format.md, "Marks that could not be trusted"): an
    entry with ``status`` "unreliable" and the ``reason``, no residual (not fitted), added
    to ``marks``; returns the notes: the measurement's finding about the sheet's grid
    declaration (measure/grid_declaration.py) and one naming the unreliable marks."""
    notes = [w for w in measurement.warnings if w.startswith("sheet.grid.origin_mm")]
    bad = []
    for m in session.marks:
        mm = measurement.marks.get(m.id)
        if mm is None or mm.status == "ok" or m.id in marks:
            continue
        marks[m.id] = {"measured_mm": np.asarray(mm.xy_mm, float).tolist(),
                       "status": mm.status, "reason": mm.reason, "role": m.role,
                       "joints_deg": [float(v) for v in m.joints_deg],
                       "n_photos": int(mm.n_photos), **measurement.mark_json(m.id)}
        bad.append(f"{m.id} ({mm.reason})")
    if bad:
        notes.append(f"{len(bad)} mark(s) left out of the fit as unreliable: "
                     + "; ".join(bad))
    return notes


def _target_errors(session: Session, data: MarkData) -> list[dict]:
    """Absolute error (measured minus target) of marks that carry ``target_mm``."""
    pos = dict(zip(data.ids, data.xy_mm))
    out = []
    for m in session.marks:
        if m.target_mm is not None and m.id in pos:
            err = pos[m.id] - np.asarray(m.target_mm)
            out.append({"id": m.id, "target_mm": list(m.target_mm),
                        "measured_mm": pos[m.id].tolist(), "error_mm": err.tolist(),
                        "error_norm_mm": float(np.hypot(*err))})
    return out


def compare_truth(path: Path, cal: CalibrationResult) -> dict:
    """Calibrated minus true parameters (synthetic data only; read only when asked)."""
    t = read_json(path)
    tp, cp = t["params"], cal.params
    out = {"L1_mm": cp["L1_mm"] - tp["L1_mm"], "L2_mm": cp["L2_mm"] - tp["L2_mm"],
           "joint_zero_deg": [cp["joint_zero_deg"][k] - tp["joint_zero_deg"][k] for k in (0, 1)],
           "base_mm": [cp["base_mm"][k] - tp["base_mm"][k] for k in (0, 1)],
           "true_effects": t.get("effects", [])}
    tm = t.get("marks", {})
    errs = [np.subtract(v["measured_mm"], tm[k]) for k, v in cal.marks.items() if k in tm]
    if errs:
        out["mark_rms_mm"] = rms_2d(np.array(errs))
    return out


def printer_scale(sheet, effects, params: dict | None = None, *,
                  bars_mm=None) -> dict | None:
    """The printer's scale from the user's measurement of the printed bars, kept apart from
    ``sheet_affine`` (added field ``printer_scale`` of calibration.json).

    ``sheet.printed.measured_bar_mm`` = [X, Y] of the ``scale_bar_length_mm`` (100 mm) bars.
    Sheet coordinates are the file's millimetres; the print is ``x`` = X / 100 and ``y`` =
    Y / 100 times them. The photos cannot see a uniform print scale (it is the same as
    longer links), so ``uniform`` = sqrt(x y) converts the calibrated lengths (L1, L2,
    base) to physical mm; the uneven part ``x / y - 1`` appears in the photos as a
    ``sheet_affine`` stretch (arm -> sheet matrix diag(1/x, 1/y)), and
    ``sheet_affine_beyond_printer`` is what a found ``sheet_affine`` leaves once the
    printer's part is taken out (paper shrink, a tilted motion plane); ``physical_mm`` the
    calibrated link lengths times ``uniform``. None when the bars were not measured.
    ``bars_mm``: the bars as measured given to the run (``calibrate --bars-mm``), over the
    sheet's; ``source`` says which.
    """
    printed = (sheet.printed if sheet is not None else None) or {}
    mb = printed.get("measured_bar_mm") if bars_mm is None else bars_mm
    if mb is None:
        return None
    bar = float(printed.get("scale_bar_length_mm", 100.0))
    sx, sy = float(mb[0]) / bar, float(mb[1]) / bar
    out = {"x": sx, "y": sy, "uniform": float(np.sqrt(sx * sy)), "uneven": sx / sy - 1.0,
           "measured_bar_mm": [float(mb[0]), float(mb[1])], "bar_mm": bar,
           "source": ("sheet.printed.measured_bar_mm" if bars_mm is None else "--bars-mm")}
    if params:
        out["physical_mm"] = {k: float(params[k]) * out["uniform"] for k in ("L1_mm", "L2_mm")
                              if params.get(k) is not None}
    for e in effects:
        if e.get("name") == "sheet_affine" and e.get("matrix") is not None:
            m = np.asarray(e["matrix"], float)
            # found x/y stretch over the printer's (1/x)/(1/y) = y/x
            out["sheet_affine_beyond_printer"] = float(m[0, 0] * sx / (m[1, 1] * sy) - 1.0)
    return out
