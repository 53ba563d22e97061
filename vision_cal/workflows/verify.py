"""Is the robot still calibrated? A short check drawn on a fresh sheet against calibration.json.

``vision-cal design ROBOT --sheet SHEET --verify CAL.json --out check/`` plans about ten
marks across the workspace (both elbows, both approach sides) with the calibrated model;
the robot draws them on a sheet (a new one, anywhere within reach), and
``vision-cal verify CAL.json check/`` measures the photos and compares:

1. **Each mark against the calibrated prediction**, after taking out where the sheet lies:
   a new sheet sits at another place and angle, so the base (x, y) and ``z1`` (which is
   the robot's rotation to the sheet plus joint 1's zero, ``docs/conventions.md``) are
   refitted first, always. Joint 1's zero therefore cannot be checked on a new sheet.
2. **Which parameters moved**: ``L1``, ``L2`` and ``z2`` refitted on top (the one solver
   from the calibration, posed by which base parameters are free,
   :class:`vision_cal.model.kinematics.ParamMask`; the calibrated effects kept), each change
   with its std (the one covariance policy, scaled by the residual variance
   ``SSR / (2N - P)``, ``docs/conventions.md``). A change beyond ``MOVED_SIGMA`` std is
   "moved".
3. **The verdict**:

   - ``still good``: nothing moved and the marks' RMS error (sheet placement taken out) is
     within ``TOLERANCE_FACTOR`` times what the calibration promised (its held-out RMS, or
     the check's own measurement noise when that is larger);
   - ``re-zero joint 2: add -0.040 deg to its controller offset``: only ``z2`` moved (by
     +0.040 deg here) and refitting it alone brings the marks back within that bound; the
     figure is what to add to the controller's joint offset, in the report's one sign
     convention (``vision_cal.dataset.nominal.rezero``: or enter ``z2 + delta`` in the
     OLP; verify.json ``rezero``);
   - ``recalibrate``: anything else (a link, several parameters, or errors no single zero
     explains: a changed backlash, a bent link).

The estimator's own code is used (measurement, model, Jacobian); the result is a frozen
:class:`VerifyResult` and ``verify.json`` (atomic) in the output folder.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vision_cal.estimate.plausible import LINK_RATIO, own_marks_offset
from vision_cal.dataset.calibration import load_calibration
from vision_cal.dataset.camera_block import check_cameras
from vision_cal.dataset.fields import FieldReader
from vision_cal.dataset.io import atomic_write_json
from vision_cal.dataset.nominal import SIGN_CONVENTION, rezero
from vision_cal.dataset.session import load_session
from vision_cal.dataset.valid_for import check as check_valid_for
from vision_cal.dataset.valid_for import enforce as enforce_valid_for
from vision_cal.dataset.valid_for import of as valid_for_of
from vision_cal.design.iso9283 import ap_rp
from vision_cal.errors import CalibrationError, VisionCalError
from vision_cal.plan.extrapolation import beyond_deg, std_at_mm, std_limit_mm
from vision_cal.workflows.pipeline import measure_marks
from vision_cal.model.kinematics import ParamMask
from vision_cal.model.rms import rms_2d
from vision_cal.model.solve import solve

#: the calibrations verify can check: pen marks fitted in one sheet's frame (a joint
#: calibration's placements too: OUT/<folder>/calibration.json)
CHECKABLE_METHODS = ("lsq", "paper", "lsq-placements")
MOVED_SIGMA = 4.0          # a parameter moved when its change exceeds this many std
TOLERANCE_FACTOR = 2.0     # still good: RMS within this factor of the promised error
PLACEMENT = ParamMask.of("z1", "base_x_mm", "base_y_mm")   # where the sheet lies (always refitted)
CHECKED = ParamMask.of("L1_mm", "L2_mm", "z2")              # what a new sheet can check
LABELS = ("L1_mm", "L2_mm", "z1_deg", "z2_deg", "base_x_mm", "base_y_mm")
UNIT = (1.0, 1.0, 180 / np.pi, 180 / np.pi, 1.0, 1.0)   # internal vector -> file units


@dataclass(frozen=True)
class VerifyResult:
    """``marks``: id -> {measured_mm, predicted_mm, error_mm, error_norm_mm};
    ``rms_mm``: 2-D RMS error against the calibration as is (``as_calibrated``), with the
    sheet placement taken out (``sheet_placed``) and after refitting L1, L2, z2
    (``refitted``); ``changes``: label -> {delta, std, sigmas, moved} (file units);
    ``bound_mm``: the "still good" bound; ``verdict``, ``reasons``."""

    marks: dict
    rms_mm: dict
    changes: dict
    bound_mm: float
    verdict: str
    reasons: tuple[str, ...]
    iso9283: dict | None = None   # point -> {n, AP_mm, RP_mm, ...} (design --iso9283)
    rezero: dict | None = None    # re-zero a joint: dataset/nominal.rezero (its actions)

    def to_json(self) -> dict:
        d = {"format": "vision-cal/verify/1", "verdict": self.verdict,
             "reasons": list(self.reasons), "rms_mm": self.rms_mm,
             "bound_mm": self.bound_mm, "changes": self.changes, "marks": self.marks,
             "iso9283": self.iso9283,
             "thresholds": {"moved_sigma": MOVED_SIGMA, "tolerance_factor": TOLERANCE_FACTOR}}
        if self.rezero is not None:   # added fields: the re-zeroing, in one convention
            d["rezero"] = {k: v for k, v in self.rezero.items() if k != "actions"}
            d["sign_convention"] = SIGN_CONVENTION
        return d


def _fit(model, q, s, xy, free: ParamMask):
    """The base parameters ``free`` refitted from ``model`` (its effects held): (model,
    residual (N, 2), std (6,) of the base vector, internal units: NaN where held, inf
    where the check cannot fix it)."""
    P = len(model.vector)

    def residual(v):
        return (model.with_vector(v).predict(q, s) - xy).ravel()

    def jac(v):
        return model.with_vector(v).jacobian(q, s).reshape(-1, P)

    sol = solve(residual, model.vector, jac=jac, free=free.over(P))
    if not sol:
        raise CalibrationError(f"the check's marks could not be fitted: {sol.reason}")
    fitted = model.with_vector(sol.x)
    std = np.full(6, np.nan)
    std[free.array] = sol.covariance(free.labels).std
    return fitted, xy - fitted.predict(q, s), std


def compare(model, cal_doc: dict, ids, q_deg, approach, xy_mm, *,
            noise_floor_mm: float | None = None, iso=None) -> VerifyResult:
    """The check's measured marks against the calibrated ``model`` (see the module).

    ``iso``: ISO 9283 visits ``(ids, q_deg, approach, xy_mm, point per id)``, judged with
    the placement fitted on the check's marks (``vision_cal.design.iso9283``)."""
    q = np.asarray(q_deg, float).reshape(-1, 2)
    s = np.asarray(approach, float).reshape(-1, 2)
    xy = np.asarray(xy_mm, float).reshape(-1, 2)
    if len(q) < 5:
        raise CalibrationError(f"{len(q)} marks were measured: a check needs at least 5 "
                               "(L1, L2, z2 and where the sheet lies)")
    raw = xy - model.predict(q, s)
    placed, res_p, _ = _fit(model, q, s, xy, PLACEMENT)
    refit, res_f, std = _fit(placed, q, s, xy, PLACEMENT | CHECKED)
    delta = (refit.vector[:6] - model.vector[:6]) * np.array(UNIT)
    std_of = dict(enumerate(std * np.array(UNIT)))
    changes, moved = {}, []
    for i in map(int, np.flatnonzero(CHECKED.array)):
        sig = float(abs(delta[i]) / std_of[i]) if std_of[i] > 0 else float("inf")
        m = sig > MOVED_SIGMA
        changes[LABELS[i]] = {"delta": float(delta[i]), "std": float(std_of[i]),
                              "sigmas": sig, "moved": m}
        if m:
            moved.append(i)
    for i in map(int, np.flatnonzero(PLACEMENT.array)):   # the sheet: reported, never judged
        changes[LABELS[i]] = {"delta": float(delta[i]), "std": float(std_of[i]),
                              "sheet_placement": True}
    val = (cal_doc.get("validation_rms_mm") or {}).get("final_model")
    promised = float(val) if isinstance(val, (int, float)) else float(
        (cal_doc.get("residual_rms_mm") or {}).get("final_model") or 0.0)
    bound = TOLERANCE_FACTOR * max(promised, float(noise_floor_mm or 0.0), 1e-6)
    rms = {"as_calibrated": rms_2d(raw), "sheet_placed": rms_2d(res_p), "refitted": rms_2d(res_f)}
    reasons, rz = [], None
    if not moved and rms["sheet_placed"] <= bound:
        verdict = "still good"
        reasons.append(f"the marks miss the calibrated prediction by {rms['sheet_placed']:.4f} mm "
                       f"RMS (the sheet's placement taken out), within {bound:.4f} mm "
                       f"({TOLERANCE_FACTOR:g} x the promised {promised:.4f} mm); no parameter "
                       f"moved beyond {MOVED_SIGMA:g} std")
    elif moved == [3]:
        z2_only, res_z, _ = _fit(placed, q, s, xy, PLACEMENT | ParamMask.of("z2"))
        d = float((z2_only.vector[3] - model.vector[3]) * UNIT[3])
        if rms_2d(res_z) <= bound:
            rz = rezero(2, d, model.params.z2_deg)
            verdict = (f"re-zero joint 2: add {rz['add_to_offset_deg']:+.3f} deg to its "
                       "controller offset")
            reasons.append(f"joint 2's zero moved by {d:+.4f} deg since the calibration "
                           f"({changes['z2_deg']['sigmas']:.1f} std); with it refitted alone "
                           f"the marks miss by {rms_2d(res_z):.4f} mm RMS, within the "
                           f"{bound:.4f} mm bound")
            reasons += rz["actions"]
        else:
            verdict = "recalibrate"
            reasons.append(f"joint 2's zero moved by {d:+.4f} deg, but the marks still miss by "
                           f"{rms_2d(res_z):.4f} mm RMS with it refitted (bound {bound:.4f} mm)")
    else:
        verdict = "recalibrate"
        if moved:
            reasons.append("moved: " + ", ".join(
                f"{LABELS[i]} {changes[LABELS[i]]['delta']:+.4f} (std "
                f"{changes[LABELS[i]]['std']:.4f}, {changes[LABELS[i]]['sigmas']:.1f} std)"
                for i in moved))
        if rms["refitted"] > bound:
            reasons.append(f"the marks miss by {rms['refitted']:.4f} mm RMS even with L1, L2, z2 "
                           f"refitted (bound {bound:.4f} mm): something the base parameters do "
                           "not explain changed (backlash, a link, the pen)")
        elif not moved:
            reasons.append(f"the marks miss by {rms['sheet_placed']:.4f} mm RMS (bound "
                           f"{bound:.4f} mm)")
    pred = placed.predict(q, s)
    marks = {mid: {"measured_mm": xy[k].tolist(), "predicted_mm": pred[k].tolist(),
                   "error_mm": (xy[k] - pred[k]).tolist(),
                   "error_norm_mm": float(np.hypot(*(xy[k] - pred[k])))}
             for k, mid in enumerate(ids)}
    iso_out = None
    if iso is not None and len(iso[0]):
        iid, iq, isg, ixy, ipt = iso
        e = np.asarray(ixy, float) - placed.predict(np.asarray(iq, float), np.asarray(isg, float))
        iso_out = {}
        for name in sorted(set(ipt)):
            k = [i for i, p in enumerate(ipt) if p == name]
            iso_out[name] = ap_rp(e[k])
        for i, mid in enumerate(iid):
            marks[mid] = {"measured_mm": list(map(float, ixy[i])),
                          "predicted_mm": (np.asarray(ixy[i]) - e[i]).tolist(),
                          "error_mm": e[i].tolist(), "error_norm_mm": float(np.hypot(*e[i])),
                          "iso9283_point": ipt[i]}
    return VerifyResult(marks, rms, changes, float(bound), verdict, tuple(reasons), iso_out, rz)


def check_verifiable(model, doc: dict, path, session) -> None:
    """Refuse (one line naming ``path`` and the field, exit 2) a calibration verify cannot
    check a drawn check against: another ``method`` (a camera on the arm: no marks to
    compare), another ``frame`` (a joint calibration of several placements is in the robot
    frame), units that are not mm and degrees (its links beyond x0.7..x1.4 of the check's
    robot block, or its own marks not where its parameters put them), a verdict of ``not
    reliable`` or none it knows, or no promised error to hold the check to."""
    r = FieldReader(str(path))
    method = doc.get("method")
    if method not in CHECKABLE_METHODS:
        r.fail("method", f"{method!r}: verify checks a pen-mark calibration (method "
                         f"{' or '.join(CHECKABLE_METHODS)}) against marks drawn with design "
                         "--verify" + ("; check a camera on the arm with a new handeye run"
                                       if method == "arm_camera" else ""))
    frame = doc.get("frame", "sheet")
    if frame != "sheet":
        r.fail("frame", f"{frame!r}: verify checks a calibration in its sheet's frame; for a "
                        "joint calibration of several placements, verify one placement's "
                        "own calibration.json (OUT/<folder>/calibration.json)")
    v = doc.get("verdict")
    if v is not None:
        status = v.get("status") if isinstance(v, dict) else None
        if status == "not reliable":
            why = "; ".join(str(x) for x in (v.get("reasons") or [])[:2])
            r.fail("verdict.status", "'not reliable': there is no promise to check"
                                     + (f" ({why})" if why else "") + "; calibrate again")
        if status not in ("ready", "check"):
            r.fail("verdict.status", f"expected ready, check or not reliable, got {status!r}")
    promised = [((doc.get(k) or {}).get("final_model") if isinstance(doc.get(k), dict) else None)
                for k in ("validation_rms_mm", "residual_rms_mm")]
    if not any(isinstance(x, (int, float)) and x > 0 for x in promised):
        r.fail("residual_rms_mm", "missing: the calibration promises no error (no "
                                  "validation_rms_mm or residual_rms_mm final_model) to hold "
                                  "the check to")
    p, nom = model.params, session.robot
    for name, got, want in (("L1_mm", p.L1_mm, nom.L1_mm), ("L2_mm", p.L2_mm, nom.L2_mm)):
        ratio = got / want
        if not LINK_RATIO[0] <= ratio <= LINK_RATIO[1]:
            r.fail(f"params.{name}", f"{got:.6g} mm against the check's robot block {want:g} mm "
                                     f"({ratio:.3g}x, {session.path}): "
                                     + ("lengths in metres?" if 5e-4 < ratio < 2e-3 else
                                        "not this robot's calibration, or not in mm"))
    _check_own_marks(model, doc, r)
    check_cameras(doc, str(path))          # a still camera it carries: the one validator


def _check_own_marks(model, doc: dict, r: FieldReader) -> None:
    """The calibration's own marks lie where its parameters put them (its units are the
    marks': mm and degrees; the owner: ``estimate/plausible.own_marks_offset``)."""
    off = own_marks_offset(model, doc)
    if off is not None:
        r.fail("params", f"its own marks lie {off[0]:.3g} mm RMS from where its parameters "
                         f"put them (it fitted {off[1]:.3g} mm): {off[2]} verify reads mm "
                         "and degrees")


def verify_folder(cal_path, folder, *, out_dir, jobs: int | None = None,
                  progress: bool = False, force: bool = False
                  ) -> tuple[VerifyResult, Path, list[str]]:
    """Measure the check's photos in ``folder`` and compare them with ``cal_path``; writes
    ``out_dir/verify.json``. The check's marks are first checked against the calibration's
    ``valid_for`` (:mod:`vision_cal.dataset.valid_for`): a mark outside it compares the
    check with an extrapolation, refused unless ``force`` (then said in verify.json
    ``outside_valid_for`` and in the lines returned, for the console)."""
    model, doc = load_calibration(cal_path)
    session = load_session(folder)
    check_verifiable(model, doc, cal_path, session)
    out_dir = Path(out_dir)
    if out_dir.resolve() == Path(folder).resolve():
        raise VisionCalError("is the check's folder: the input folder is never written to",
                             file=str(out_dir), field="--out")
    q, a = session.joints_deg.tolist(), session.approach.astype(int).tolist()
    outside = check_valid_for(
        valid_for_of(doc, file=str(cal_path)), cal=str(cal_path),
        ids=[m.id for m in session.marks], joints_deg=q, approach=a,
        joint4_deg=session.j4_deg.tolist() if session.uses_joint4 else None,
        # beyond the marks' joints as far as the calibration's own expected error holds
        std_mm=std_at_mm(model, doc, [v[:2] for v in q], [v[:2] for v in a],
                         file=str(cal_path)),
        std_limit_mm=std_limit_mm(model, doc, file=str(cal_path)), beyond_deg=beyond_deg(doc))
    said = enforce_valid_for(outside, file=str(cal_path), force=force,
                             what=f"{folder}/session.json marks")
    measurement, data, missing = measure_marks(session, out_dir=out_dir, jobs=jobs,
                                               progress=progress)
    noise = (float(np.sqrt(2 * np.mean(data.sigma_mm**2)))
             if data.sigma_mm is not None and len(data.sigma_mm) else None)
    design = session.raw.get("design") if isinstance(session.raw, dict) else None
    iso_info = (((design or {}).get("iso9283") or {}).get("marks")) or {}
    k = np.array([i not in iso_info for i in data.ids], bool)
    iso = None
    if iso_info:
        j = ~k
        iso = ([i for i, s in zip(data.ids, j) if s], data.q_deg[j], data.approach[j],
               data.xy_mm[j], [iso_info[i]["point"] for i, s in zip(data.ids, j) if s])
    r = compare(model, doc, [i for i, s in zip(data.ids, k) if s], data.q_deg[k],
                data.approach[k], data.xy_mm[k], noise_floor_mm=noise, iso=iso)
    out = r.to_json()
    out.update(calibration=str(cal_path), folder=str(folder), missing_marks=missing,
               noise_floor_mm=noise)
    if outside:   # written because of force: the extrapolation stated in the file
        out["outside_valid_for"] = [o.to_json() for o in outside]
    path = atomic_write_json(out_dir / "verify.json", out)
    return r, path, said
