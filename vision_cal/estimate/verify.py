"""Is the robot still calibrated? A check drawn on a fresh sheet, posed to the estimator.

``vision-cal design ROBOT --sheet SHEET --verify CAL.json --out check/`` plans about ten
marks across the workspace (both elbows, both approach sides) with the calibrated model;
the robot draws them on a sheet (a new one, anywhere within reach), and
``vision-cal verify CAL.json check/`` measures the photos
(:func:`vision_cal.actions.verify.verify_folder`) and poses the check here
(:func:`compare`): the data are the check's marks, the free parameters a
:class:`~vision_cal.model.kinematics.ParamMask` of the calibrated model (its effects held),
fitted by the one solver with the one covariance policy:

1. **Each mark against the calibrated prediction**, after taking out where the sheet lies:
   a new sheet sits at another place and angle, so the base (x, y) and ``z1`` (which is
   the robot's rotation to the sheet plus joint 1's zero, ``docs/conventions.md``) are
   refitted first, always (:data:`PLACEMENT`). Joint 1's zero therefore cannot be checked
   on a new sheet.
2. **Which parameters moved**: ``L1``, ``L2`` and ``z2`` refitted on top (:data:`CHECKED`),
   each change with its std (scaled by the residual variance ``SSR / (2N - P)``,
   ``docs/conventions.md``). A change beyond ``config.verify.moved_sigma`` std is "moved".
3. **The verdict** (:func:`_verdict`; its thresholds ``config.verify``, the calibration's
   own record):

   - ``still good``: nothing moved and the marks' RMS error (sheet placement taken out) is
     within ``tolerance_factor`` times what the calibration promised (its held-out RMS, or
     the check's own measurement noise when that is larger);
   - ``re-zero joint 2: add -0.040 deg to its controller offset``: only ``z2`` moved (by
     +0.040 deg here) and refitting it alone brings the marks back within that bound; the
     figure is what to add to the controller's joint offset, in the report's one sign
     convention (``vision_cal.dataset.nominal.rezero``: or enter ``z2 + delta`` in the
     OLP; verify.json ``rezero``);
   - ``recalibrate``: anything else (a link, several parameters, or errors no single zero
     explains: a changed backlash, a bent link).

ISO 9283 visits (``design --iso9283``) give each point's AP and RP (:func:`ap_rp`) with the
placement fitted on the check's marks. The result is a frozen :class:`VerifyResult`,
``verify.json`` (docs/format.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vision_cal.config import EstimatorConfig, VerifyConfig
from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.dataset.nominal import SIGN_CONVENTION, rezero
from vision_cal.errors import CalibrationError
from vision_cal.model.kinematics import ParamMask
from vision_cal.model.rms import rms_2d
from vision_cal.model.solve import solve

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
    ``bound_mm``: the "still good" bound; ``verdict``, ``reasons``; ``thresholds``: the
    ``config.verify`` it was judged with."""

    marks: dict
    rms_mm: dict
    changes: dict
    bound_mm: float
    verdict: str
    reasons: tuple[str, ...]
    iso9283: dict | None = None   # point -> {n, AP_mm, RP_mm, ...} (design --iso9283)
    rezero: dict | None = None    # re-zero a joint: dataset/nominal.rezero (its actions)
    thresholds: VerifyConfig = field(default_factory=VerifyConfig)

    def to_json(self) -> dict:
        d = {"format": "vision-cal/verify/1", "verdict": self.verdict,
             "reasons": list(self.reasons), "rms_mm": self.rms_mm,
             "bound_mm": self.bound_mm, "changes": self.changes, "marks": self.marks,
             "iso9283": self.iso9283,
             "thresholds": {"moved_sigma": self.thresholds.moved_sigma,
                            "tolerance_factor": self.thresholds.tolerance_factor}}
        if self.rezero is not None:   # added fields: the re-zeroing, in one convention
            d["rezero"] = {k: v for k, v in self.rezero.items() if k != "actions"}
            d["sign_convention"] = SIGN_CONVENTION
        return d


def refit(model, q, s, xy, free: ParamMask):
    """The base parameters ``free`` refitted from ``model`` (its effects held) to the marks
    ``xy`` (N, 2) at joints ``q`` and approach ``s``: (model, residual (N, 2), std (6,) of
    the base vector, internal units: NaN where held, inf where the marks cannot fix it)."""
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


def ap_rp(errors_mm: np.ndarray) -> dict:
    """AP and RP (mm) of one point from its visits' 2-D errors (N, 2) (ISO 9283 in the
    plane: AP = |mean(e)|, RP = mean(l) + 3 std(l) with ``l = |e - mean(e)|``,
    :mod:`vision_cal.design.iso9283`)."""
    e = np.asarray(errors_mm, float).reshape(-1, 2)
    mean = e.mean(axis=0)
    ell = np.hypot(*(e - mean).T)
    sd = float(np.std(ell, ddof=1)) if len(ell) > 1 else float("nan")
    return {"n": int(len(e)), "AP_mm": float(np.hypot(*mean)), "mean_error_mm": mean.tolist(),
            "RP_mm": float(ell.mean() + 3 * sd), "l_mean_mm": float(ell.mean()),
            "l_std_mm": sd}


def compare(model, cal, ids, q_deg, approach, xy_mm, *,
            noise_floor_mm: float | None = None, iso=None) -> VerifyResult:
    """The check's measured marks against the calibrated ``model`` (see the module); ``cal``:
    the calibration (its :class:`CalibrationResult`, or the document), for the error it
    promised and the thresholds it recorded (``config.verify``).

    ``iso``: ISO 9283 visits ``(ids, q_deg, approach, xy_mm, point per id)``, judged with
    the placement fitted on the check's marks (:mod:`vision_cal.design.iso9283`)."""
    if not isinstance(cal, CalibrationResult):
        cal = CalibrationResult.from_json(cal)
    cfg = EstimatorConfig.from_json(cal.config).verify
    q = np.asarray(q_deg, float).reshape(-1, 2)
    s = np.asarray(approach, float).reshape(-1, 2)
    xy = np.asarray(xy_mm, float).reshape(-1, 2)
    if len(q) < 5:
        raise CalibrationError(f"{len(q)} marks were measured: a check needs at least 5 "
                               "(L1, L2, z2 and where the sheet lies)")
    raw = xy - model.predict(q, s)
    placed, res_p, _ = refit(model, q, s, xy, PLACEMENT)
    fitted, res_f, std = refit(placed, q, s, xy, PLACEMENT | CHECKED)
    delta = (fitted.vector[:6] - model.vector[:6]) * np.array(UNIT)
    std_of = dict(enumerate(std * np.array(UNIT)))
    changes, moved = {}, []
    for i in map(int, np.flatnonzero(CHECKED.array)):
        sig = float(abs(delta[i]) / std_of[i]) if std_of[i] > 0 else float("inf")
        m = sig > cfg.moved_sigma
        changes[LABELS[i]] = {"delta": float(delta[i]), "std": float(std_of[i]),
                              "sigmas": sig, "moved": m}
        if m:
            moved.append(i)
    for i in map(int, np.flatnonzero(PLACEMENT.array)):   # the sheet: reported, never judged
        changes[LABELS[i]] = {"delta": float(delta[i]), "std": float(std_of[i]),
                              "sheet_placement": True}
    val, fit_rms = cal.validation_rms_mm, cal.residual_rms_mm
    val = None if val is None else val.final_model
    promised = float(val) if isinstance(val, (int, float)) else float(
        (None if fit_rms is None else fit_rms.final_model) or 0.0)
    floor = float(noise_floor_mm or 0.0)
    bound = cfg.tolerance_factor * max(promised, floor, 1e-6)
    basis = (f"the check's noise floor {floor:.4f} mm" if floor > promised
             else f"the promised {promised:.4f} mm")
    rms = {"as_calibrated": rms_2d(raw), "sheet_placed": rms_2d(res_p), "refitted": rms_2d(res_f)}
    verdict, reasons, rz = _verdict(model, placed, (q, s, xy), moved, changes, rms, bound,
                                    basis, cfg)
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
    return VerifyResult(marks, rms, changes, float(bound), verdict, tuple(reasons), iso_out, rz,
                        cfg)


def _verdict(model, placed, marks, moved: list, changes: dict, rms: dict, bound: float,
             basis: str, cfg: VerifyConfig) -> tuple[str, list[str], dict | None]:
    """(verdict, reasons, the re-zeroing or None) of a check (the module's rule): ``marks``
    (q, s, xy) the check's, ``moved`` the indices of the base parameters beyond
    ``cfg.moved_sigma``, ``basis`` what the bound is a multiple of (the promised error or
    the check's noise floor, the larger, with its value)."""
    q, s, xy = marks
    reasons, rz = [], None
    if not moved and rms["sheet_placed"] <= bound:
        verdict = "still good"
        reasons.append(f"the marks miss the calibrated prediction by {rms['sheet_placed']:.4f} mm "
                       f"RMS (the sheet's placement taken out), within {bound:.4f} mm "
                       f"({cfg.tolerance_factor:g} x {basis}); no "
                       f"parameter moved beyond {cfg.moved_sigma:g} std")
    elif moved == [3]:
        z2_only, res_z, _ = refit(placed, q, s, xy, PLACEMENT | ParamMask.of("z2"))
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
    return verdict, reasons, rz
