"""What a robotics engineer reads first: the headline, the actions, the provenance.

Everything here turns calibration.json (and the loop's document when a loop ran) into
JSON-ready dicts that ``report.json`` holds and ``report.html`` renders; no figure is
computed twice: the RMS values are calibration.json's, copied, never recomputed.

The verdict's "expected target error (95 %)" is the radius that holds 95 % of the errors
of a circular normal 2-D error whose RMS is the held-out RMS of the final model:
``r95 = sqrt(-2 ln 0.05) / sqrt(2) * rms = 1.731 * rms``
(:data:`vision_cal.estimate.verdict.R95_PER_RMS`). The
held-out marks were not fitted, so their RMS includes both the model's uncertainty and
the measurement noise of the marks themselves (a conservative figure).
"""

from __future__ import annotations

import math

import vision_cal
from vision_cal.dataset.nominal import (SIGN_CONVENTION, controller_offsets, offsets_text)
from vision_cal.report.summary import describe_effect, verdict_block


def headline(doc: dict, loop: dict | None = None) -> dict:
    """What was calibrated, accuracy before/after, effects, verdict (JSON-ready)."""
    marks = {k: m for k, m in doc.get("marks", {}).items() if m.get("status", "ok") == "ok"}
    roles = [m.get("role", "calibration") for m in marks.values()]
    n_fit = roles.count("calibration")
    n_val = roles.count("validation")
    photos = doc.get("images", [])
    n_ok = sum(im.get("status") == "ok" for im in photos)
    effects = [e for e in doc.get("effects", []) if e["name"] != "unexplained"]
    what = ("SCARA base model (L1, L2, joint zeros z1 z2, base x y)"
            + (" + " + ", ".join(_effect_name(e) for e in effects) if effects else "")
            + f", {doc.get('method', 'lsq')} fit of {n_fit} marks"
            + (f" ({n_val} held out)" if n_val else "")
            + (f", measured on {n_ok} of {len(photos)} photos" if photos else ""))
    r, v = doc.get("residual_rms_mm", {}), doc.get("validation_rms_mm", {})
    acc = [{"what": "fitted marks (residual RMS)", "key": "residual_rms_mm",
            "before_mm": r.get("base_model"), "after_mm": r.get("final_model"), "n": n_fit}]
    if v.get("final_model") is not None:
        acc.append({"what": f"held-out marks ({v.get('kind', 'validation')}, RMS)",
                    "key": "validation_rms_mm", "before_mm": v.get("base_model"),
                    "after_mm": v.get("final_model"),
                    "n": n_val if v.get("kind") == "validation marks" else n_fit})
    if loop and loop.get("summary"):
        s = loop["summary"]
        acc.append({"what": "targets drawn by the loop (absolute error RMS, measured)",
                    "key": "loop.summary", "before_mm": s["before"]["rms_mm"],
                    "after_mm": s["after"]["rms_mm"],
                    "n": s["after"]["n_measured"], "n_before": s["before"]["n_measured"],
                    "of": s["n_targets"]})
    eff = [{"name": e["name"], "text": describe_effect(e, evidence=False), **_size(e)}
           for e in effects]
    return {"calibrated": what, "accuracy": acc, "effects": eff,
            "verdict": verdict(doc, loop)}


def _effect_name(e: dict) -> str:
    return e["name"] + (f" (joint {e['joint']})" if "joint" in e else "")


def _size(e: dict) -> dict:
    for key, unit in (("deg", "deg"), ("scale", "")):
        if key in e:
            return {"value": e[key], "std": e.get("std"), "unit": unit}
    return {}


def verdict(doc: dict, loop: dict | None = None) -> dict:
    """``{"status": ready | check | not reliable, "text": ..., "expected_r95_mm"}``: the
    document's own ``verdict`` block (written by :mod:`vision_cal.estimate.verdict`), never
    judged here; the loop's measured figures appended."""
    v = verdict_block(doc)
    tail = ""
    if loop and loop.get("summary", {}).get("after", {}).get("rms_mm") is not None:
        a = loop["summary"]["after"]
        tail = (f"; measured on {a['n_measured']} targets: RMS {a['rms_mm']:.4f} mm, "
                f"max {a['max_mm']:.4f} mm")
    out = {"status": v["status"], "text": v["text"] + tail, "reasons": list(v["reasons"]),
           "residual_over_floor": v.get("residual_over_floor")}
    if v.get("expected_target_error_mm") is not None:
        out["expected_r95_mm"] = v["expected_target_error_mm"]
    return out


def actions(doc: dict, *, calibration_path: str = "OUT/calibration.json") -> dict:
    """The numbers to enter in the controller or OLP, and the commands for the rest."""
    p, s, n = doc["params"], doc.get("std") or {}, doc.get("nominal") or {}

    def g(d, key, k=None):
        v = d.get(key) if d else None
        return v[k] if (v is not None and k is not None) else v

    olp = []   # "nominal": the robot file the controller runs (dataset/nominal)
    for label, key, k, unit in (("L1 (link 1 length)", "L1_mm", None, "mm"),
                                ("L2 (link 2 length)", "L2_mm", None, "mm"),
                                ("z1 (joint 1 zero, link 1 angle from sheet x)",
                                 "joint_zero_deg", 0, "deg"),
                                ("z2 (joint 2 zero, link 2 angle from link 1)",
                                 "joint_zero_deg", 1, "deg"),
                                ("base x (joint 1 axis, sheet frame)", "base_mm", 0, "mm"),
                                ("base y (joint 1 axis, sheet frame)", "base_mm", 1, "mm")):
        olp.append({"name": label, "unit": unit, "nominal": g(n, key, k),
                    "calibrated": g(p, key, k), "std": g(s, key, k)})
    offsets = controller_offsets(doc)   # relative to the robot file (dataset/nominal)
    controller_effects, planner_effects = [], []
    for e in doc.get("effects", []):
        if e["name"] == "joint_scale":
            controller_effects.append(
                {"name": "joint_scale", "joint": e["joint"],
                 "text": f"joint {e['joint']} gear ratio: divide the controller's ratio "
                         f"(motor turns per joint turn) by 1 + s = {1 + e['scale']:.6f}, or "
                         "leave it and let the planner compensate"})
        if e["name"] in ("joint_backlash", "joint_scale", "joint_cyclic", "sheet_affine",
                         "sheet_height"):
            planner_effects.append(_effect_name(e))
    cal = calibration_path
    return {
        "olp_model": olp,
        "sign_convention": SIGN_CONVENTION,
        "controller_offsets": offsets,
        "nominal_is": "the robot file",
        "starting_model": doc.get("starting_model"),
        "controller_offsets_text": offsets_text(offsets),
        "controller_effects": controller_effects,
        "planner_effects": planner_effects,
        "commands": [
            {"what": "joint commands that hit sheet targets with every effect compensated "
                     + (f"({', '.join(planner_effects)})" if planner_effects else "")
                     + " (targets.csv: id,x_mm,y_mm)",
             "command": f"vision-cal plan {cal} targets.csv -o plan.csv "
                        "--trajectory traj.csv --program spel --robot robot.yaml"},
            {"what": "the model for ROS/OLP tools (URDF plus the effects it cannot hold)",
             "command": f"vision-cal export {cal} --urdf robot.urdf --robot robot.yaml"},
        ],
    }


def mark_rows(doc: dict, refused: dict | None = None) -> list[dict]:
    """The per-mark table: measured, residual, uncertainty, photo count, flags.

    ``refused``: mark id -> why the measurement refused it (``Measurement.refused``)."""
    outliers = set(doc.get("outliers", []))
    rows = []
    for mid, m in doc.get("marks", {}).items():
        flags = []
        if m.get("role") == "validation":
            flags.append("held out")
        if mid in outliers:
            flags.append("outlier (down-weighted by the robust fit)")
        if m.get("status", "ok") != "ok":
            flags.append(f"{m['status']}, left out of the fit: {m.get('reason', '')}")
        res = m.get("residual_mm") or [math.nan, math.nan]
        rows.append({"id": mid, "role": m.get("role", "calibration"),
                     "measured_mm": m.get("measured_mm"), "residual_mm": res,
                     "residual_norm_mm": math.hypot(*res),
                     "sigma_mm": m.get("sigma_mm"), "n_photos": m.get("n_photos"),
                     "flags": flags})
    for mid in doc.get("missing_marks", []):
        why = (refused or {}).get(mid) or "not found on any photo"
        rows.append({"id": mid, "role": None, "measured_mm": None, "residual_mm": None,
                     "residual_norm_mm": None, "sigma_mm": None, "n_photos": 0,
                     "flags": [f"not measured: {why}"]})
    return rows


STATISTICS = {
    "F": "F: the drop in the (weighted) residual sum of squares per added parameter, divided "
         "by the remaining residual variance; large F means the effect explains more than "
         "noise would.",
    "p": "p: the chance of an F this large if the effect were absent; an effect is kept only "
         "when p is below alpha / (number of candidates) (Bonferroni).",
    "dBIC": "dBIC: the change in the Bayesian information criterion, n ln(RSS1/RSS0) + k ln n; "
            "negative means the extra parameters pay for themselves; an effect needs "
            "dBIC < 0.",
    "held-out": "held-out RMS: the error on marks the fit did not see (validation marks, or "
                "k-fold cross-validation); an effect is kept only when it lowers it.",
}


def configuration(doc: dict) -> dict:
    """The thresholds the run used, as calibration.json recorded them (``config``; None
    for a threshold a file written before it was recorded does not have)."""
    cfg = doc.get("config") or {}

    def part(name):
        return cfg.get(name) or {}

    m, d, p = part("markers"), part("dots"), part("per_photo_offsets")
    return {
        "method": doc.get("method"),
        "diagnosis": (doc.get("diagnosis") or {}).get("thresholds"),
        "per_photo_offsets": {"gate_mm": p.get("gate_mm"), "alpha": p.get("alpha")},
        "fit": {"condition_number_limit": part("fit").get("condition_number_limit")},
        # the thresholds the verdict was judged with (empty for a file that has none)
        "verdict": dict(part("verdict")),
        "measurement": {
            "min_markers_per_photo": m.get("min_markers"),
            "min_marker_hull_fraction": m.get("min_hull_fraction"),
            "blank_photo_std": m.get("blank_photo_std"),
            "ink_darkening": d.get("ink_darkening"),
            "dot_area_ratio": [d.get("min_area_ratio"), d.get("max_area_ratio")],
            "dot_max_aspect": d.get("max_aspect"), "dot_min_solidity": d.get("min_solidity"),
            "marker_margin_mm": d.get("marker_margin_mm")},
    }


def provenance(doc: dict, *, dataset: str, out_dir: str, camera: dict | None,
               created_utc: str) -> dict:
    """Date, version, input folder, camera/lens, photos used and skipped."""
    images = doc.get("images", [])
    lens = next((e for e in doc.get("effects", []) if e["name"] == "lens_distortion"), None)
    if camera:
        K = camera.get("K") or [[None]]
        cam = (f"declared in session.json: {camera.get('size_px')} px, f {K[0][0]} px, "
               f"dist {camera.get('dist')}")
    elif lens is not None:
        cam = "not declared; a lens was found: " + describe_effect(lens, evidence=False)
    elif images:
        cam = ("not declared; estimated from the photos' marker grids, no lens distortion "
               "found beyond the noise")
    else:
        cam = "no photos (marks measured by other means)"
    return {"created_utc": created_utc, "vision_cal_version": vision_cal.__version__,
            "dataset": dataset, "out": out_dir, "camera": cam,
            "photos_used": [im["file"] for im in images if im.get("status") == "ok"],
            "photos_skipped": [{"file": im["file"], "reason": im.get("reason", "")}
                               for im in images if im.get("status") != "ok"],
            "configuration": configuration(doc)}
