"""The short text summary printed after a calibration, rendered from calibration.json."""

from __future__ import annotations

import math
import textwrap

import numpy as np

from vision_cal.dataset.nominal import controller_offsets


def _f(x, nd=3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.{nd}f}"


def _rows(doc: dict):
    p, s, n = doc["params"], doc.get("std") or {}, doc.get("nominal") or {}

    def g(d, key, k=None):
        if not d or key not in d or d[key] is None:
            return None
        v = d[key]
        return v[k] if k is not None else v

    yield "L1 [mm]", g(n, "L1_mm"), g(p, "L1_mm"), g(s, "L1_mm"), ("L1_mm", None)
    yield "L2 [mm]", g(n, "L2_mm"), g(p, "L2_mm"), g(s, "L2_mm"), ("L2_mm", None)
    yield "z1 [deg]", g(n, "joint_zero_deg", 0), g(p, "joint_zero_deg", 0), \
        g(s, "joint_zero_deg", 0), ("joint_zero_deg", 0)
    yield "z2 [deg]", g(n, "joint_zero_deg", 1), g(p, "joint_zero_deg", 1), \
        g(s, "joint_zero_deg", 1), ("joint_zero_deg", 1)
    yield "base x [mm]", g(n, "base_mm", 0), g(p, "base_mm", 0), g(s, "base_mm", 0), ("base_mm", 0)
    yield "base y [mm]", g(n, "base_mm", 1), g(p, "base_mm", 1), g(s, "base_mm", 1), ("base_mm", 1)


def format_summary(doc: dict, *, reference: dict | None = None) -> str:
    """Table-2 style comparison, effects with evidence, RMS against the noise floor."""
    targets = _target_lines(doc)
    if targets:   # a folder of compensated targets: where each landed is the answer
        return "\n".join(targets + ["", "the calibration fitted to these marks (a by-product: "
                                     "targets are not a calibration plan):",
                                     _calibration_summary(doc, reference)])
    return _calibration_summary(doc, reference)


def _target_lines(doc: dict) -> list[str]:
    """Each target's error (measured minus target, mm), its RMS and the largest."""
    t = [x for x in doc.get("targets") or [] if isinstance(x, dict) and "error_mm" in x]
    if not t:
        return []
    lines = [f"where each target landed ({len(t)} targets; measured minus target, mm):",
             f"{'target':<10}{'error x':>10}{'error y':>10}{'|error|':>10}"]
    for x in t:
        ex, ey = x["error_mm"]
        lines.append(f"{str(x['id']):<10}{ex:>+10.4f}{ey:>+10.4f}{x['error_norm_mm']:>10.4f}")
    norms = [float(x["error_norm_mm"]) for x in t]
    worst = max(t, key=lambda x: x["error_norm_mm"])
    rms = (sum(n * n for n in norms) / len(norms)) ** 0.5
    lines.append(f"targets: RMS {rms:.4f} mm, largest {worst['error_norm_mm']:.4f} mm "
                 f"({worst['id']})")
    return lines


def _camera_lines(doc: dict) -> list[str]:
    """The still cameras a calibration located: where, how well, what to run next."""
    out = []
    for k, c in enumerate(doc.get("cameras") or []):
        if not isinstance(c, dict) or "T_robot_camera" not in c:
            continue
        try:
            t = [float(c["T_robot_camera"][i][3]) for i in range(3)]
            size = "x".join(str(int(v)) for v in c.get("size_px", []))
        except (TypeError, ValueError, IndexError, KeyError):
            continue
        rms = c.get("corner_rms_px")
        out.append(f"still camera {k} ({len(c.get('images') or [])} photos, {size} px, lens "
                   f"{c.get('intrinsics', 'declared')}): at x {t[0]:.2f} y {t[1]:.2f} z "
                   f"{t[2]:.2f} mm in the robot frame"
                   + (f", corner RMS {rms:.3f} px" if isinstance(rms, (int, float)) else "")
                   + "; map its pixels with `vision-cal locate CALIBRATION.json --pixel U V`")
        if c.get("note"):
            out.append(f"  note: {c['note']}")
    return out


def _print_replication_lines(pr) -> list[str]:
    """calibration.json ``print`` measured from several places (issue 37): applied or why
    not, and the halves' sentence."""
    if not isinstance(pr, dict) or pr.get("source") == "one place" or "status" not in pr:
        return []
    head = (f"sheet as printed ({pr.get('source')}, {pr.get('n_places')} places): "
            + ("applied" if pr.get("applied") else
               f"not applied ({pr.get('status')}): {pr.get('reason')}"))
    rep = (pr.get("replication") or {}).get("text")
    return [head] + ([f"  replication: {rep}"] if rep else [])


def _calibration_summary(doc: dict, reference: dict | None) -> str:
    ref = (reference or {}).get("params")
    head = f"{'parameter':<12}{'robot file':>11}{'calibrated':>13}{'std':>10}"
    if ref:
        head += f"{(reference.get('label') or 'reference'):>16}"
    lines = [f"calibration ({doc.get('method', 'lsq')}): "
             f"{len(doc.get('marks', {}))} marks", head, "-" * len(head)]
    for name, nom, cal, std, (key, k) in _rows(doc):
        row = f"{name:<12}{_f(nom):>11}{_f(cal):>13}{('+-' + _f(std, 4)) if std is not None else '-':>10}"
        if ref:
            v = ref.get(key)
            v = v[k] if (v is not None and k is not None) else v
            row += f"{_f(v, 1):>16}"
        lines.append(row)
    if ref and "note" in reference:
        lines.append(f"  ({reference['note']})")
    sm = doc.get("starting_model")
    if isinstance(sm, dict):
        lines.append(f"  (the plan was placed with a starting model, {sm.get('source', '')}: "
                     f"z1 {_f(sm['joint_zero_deg'][0], 4)}, z2 {_f(sm['joint_zero_deg'][1], 4)} "
                     "deg; every nominal and offset here is the robot file's)")
    offsets = controller_offsets(doc)
    if offsets:   # two ways, one a line (the sentence itself: offsets_text, the report's)
        lines += ["controller: either",
                  "  - enter the calibrated model in the OLP (and leave the controller alone), or",
                  "  - keep the robot file's model and add to the controller's joint offsets: "
                  + ", ".join(f"joint {o['joint']}: {o['add_to_offset_deg']:+.4f} deg"
                              for o in offsets)]
    effects = [e for e in doc.get("effects", []) if e["name"] != "unexplained"]
    if effects:
        lines.append("effects found:")
        for e in effects:
            lines.append("  " + describe_effect(e))
    else:
        lines.append("effects found: none (the base model explains the marks)")
    for e in doc.get("effects", []):
        if e["name"] == "unexplained":
            lines.append("  unexplained structure: " + "; ".join(e.get("seen", [])))
    for d in (doc.get("identifiability") or {}).get("not_identifiable", []):
        lines.append(f"  not identifiable by this plan: {d['label']} - {d['fix']}")
    r, v = doc.get("residual_rms_mm", {}), doc.get("validation_rms_mm", {})
    lines.append(f"residual RMS [mm]: base model {_f(r.get('base_model'), 4)} -> final "
                 f"{_f(r.get('final_model'), 4)}")
    if v.get("base_model") is not None:
        lines.append(f"held-out RMS [mm] ({v.get('kind', 'validation')}): base model "
                     f"{_f(v.get('base_model'), 4)} -> final {_f(v.get('final_model'), 4)}")
    ps = doc.get("printer_scale")
    if ps:
        line = (f"printer scale (measured bars): x {ps['x']:.5f}, y {ps['y']:.5f} (uneven "
                f"{100 * ps['uneven']:+.3f} %); physical lengths = calibrated x "
                f"{ps['uniform']:.5f}")
        phys = ps.get("physical_mm") or {}
        if phys.get("L1_mm") is not None and phys.get("L2_mm") is not None:
            line += f" (L1 {phys['L1_mm']:.3f}, L2 {phys['L2_mm']:.3f} mm)"
        if ps.get("sheet_affine_beyond_printer") is not None:
            line += (f"; sheet_affine beyond the printer "
                     f"{100 * ps['sheet_affine_beyond_printer']:+.3f} %")
        lines.append(line)
    lines += _print_replication_lines(doc.get("print"))
    if doc.get("noise_floor_mm") is not None:
        # the photos' own noise on a mark: not the verdict's noise floor (which adds the
        # robot's repeatability over the fitted marks), so named apart from it
        lines.append(f"measurement noise of a mark (2-D RMS, the photos alone) [mm]: "
                     f"{_f(doc['noise_floor_mm'], 4)}")
    for c in (doc.get("identifiability") or {}).get("high_correlations", []):
        lines.append(f"  correlated: {c['a']} ~ {c['b']} (r = {c['r']:+.3f})")
    for note in doc.get("notes", []):   # wrapped: a note is a sentence, not a screen line
        lines += textwrap.wrap(f"note: {note}", WIDTH, initial_indent="  ",
                               subsequent_indent="    ", break_on_hyphens=False,
                               break_long_words=False)
    skipped = [im for im in doc.get("images", []) if im.get("status") != "ok"]
    if skipped:
        lines.append(f"skipped photos: {len(skipped)}")
        for im in skipped:
            lines.append(f"  {im['file']}: {im.get('reason', '')}")
    if doc.get("residual_rms_mm"):
        v = verdict_block(doc)
        if v.get("floor_line"):
            lines.append(v["floor_line"])
        lines += uncertainty_lines(doc)
        lines += verdict_lines(v)
    lines += _camera_lines(doc)
    tc = doc.get("truth_comparison")
    if tc:
        lines.append("against truth.json: dL1 {} dL2 {} mm, dz1 {} dz2 {} deg, dbase {} {} mm".format(
            _f(tc["L1_mm"], 4), _f(tc["L2_mm"], 4), _f(tc["joint_zero_deg"][0], 4),
            _f(tc["joint_zero_deg"][1], 4), _f(tc["base_mm"][0], 4), _f(tc["base_mm"][1], 4)))
        if "mark_rms_mm" in tc:
            lines.append(f"  mark position RMS error against truth: {_f(tc['mark_rms_mm'], 4)} mm")
    return "\n".join(lines)


def uncertainty_lines(doc: dict) -> list[str]:
    """What the stated figures hold (issue 37), from calibration.json alone: the
    repeatability and where it comes from (``verdict.repeatability``), a target's std by
    part (``verdict.target_std``), the fit replicated by two halves of its marks
    (``replication.text``), the paper's scale (``paper_scale.text``); none for an older
    file without them."""
    out = []
    v = doc.get("verdict") if isinstance(doc.get("verdict"), dict) else {}
    rp = v.get("repeatability")
    if isinstance(rp, dict) and rp.get("mm") is not None:
        out.append(f"repeatability {rp['mm']:.4f} mm per axis ({rp.get('why', '')})")
    ts = v.get("target_std")
    if isinstance(ts, dict) and ts.get("total_mm") is not None:
        out.append(f"a target's std per axis {ts['total_mm']:.4f} mm: calibration "
                   f"{ts['calibration_mm']:.4f}, repeatability {ts['repeatability_mm']:.4f}, "
                   f"unexplained {ts['unexplained_mm']:.4f}, print {ts['print_mm']:.4f} mm "
                   f"(from {ts.get('from', '?')}; plan.csv std_mm adds the paper's scale off "
                   "the paper)")
    for key in ("replication", "paper_scale"):
        b = doc.get(key)
        if isinstance(b, dict) and b.get("text"):
            out.append(b["text"])
    return out


#: what a calibration.json without a verdict block (written before verdicts) is shown as
NO_VERDICT = "this calibration.json has no verdict (written by an older version)"


#: the console's width for a verdict's reasons (each reason a bullet, wrapped under it)
WIDTH = 100


def verdict_lines(v: dict) -> list[str]:
    """A verdict block (:func:`verdict_block`'s) as console lines: the judgement with its
    expected target error on the first, then each reason on its own, wrapped (one reason,
    one action: never one line of several hundred characters); a ``ready`` one is its
    ``text``."""
    reasons = [str(r) for r in v.get("reasons") or []]
    if v.get("status") == "ready" or not reasons:
        return [v["text"]]
    head = {"check": "check before use", "not reliable": "not reliable"}.get(
        v.get("status"), str(v.get("status")))
    e = v.get("expected_target_error_mm")
    fig = f" (expected target error {e:.3f} mm, 95 %)" if isinstance(e, (int, float)) else ""
    out = [f"{head}{fig}: {len(reasons)} reason(s)"]
    for r in reasons:
        out += textwrap.wrap(r, WIDTH, initial_indent="  - ", subsequent_indent="    ",
                             break_on_hyphens=False, break_long_words=False)
    return out


def verdict_block(doc: dict) -> dict:
    """calibration.json's ``verdict`` (status, reasons, ``text``, ``floor_line``: the
    sentences :mod:`vision_cal.estimate.verdict` wrote), read and never judged here; an older
    file's block without its ``text`` shows status and reasons, a file without a block
    :data:`NO_VERDICT`."""
    v = doc.get("verdict")
    if not isinstance(v, dict) or "status" not in v:
        return {"status": "check", "text": f"check before use: {NO_VERDICT}",
                "reasons": [NO_VERDICT]}
    v = dict(v)
    v.setdefault("reasons", [])
    if not v.get("text"):
        v["text"] = v["status"] + (": " + "; ".join(v["reasons"]) if v["reasons"] else "")
    return v


def describe_effect(e: dict, *, evidence: bool = True) -> str:
    name = e["name"]
    if name == "joint_backlash":
        s = f"joint_backlash joint {e['joint']}: {e['deg']:.4f} deg"
    elif name == "joint_scale":
        s = f"joint_scale joint {e['joint']}: {100 * e['scale']:+.4f} %"
    elif name == "joint_cyclic":
        s = (f"joint_cyclic joint {e['joint']} harmonic {e['harmonic']}: {e['deg']:.4f} deg "
             f"at phase {e['phase_deg']:.1f} deg")
    elif name == "joint_terms":
        s = f"joint_terms joint {e['joint']}: " + (e.get("description") or ", ".join(
            f"{t['coef']:+.4g} x {t['feature']}" for t in e.get("terms", [])))
        stds = [t.get("std") for t in e.get("terms", [])]
        if all(v is not None for v in stds):
            s += " (std " + ", ".join(f"{v:.2g}" for v in stds) + ")"
    elif name == "drift":
        s = f"drift (not compensable): {e.get('description') or e.get('along', '')}"
    elif name == "sheet_affine":
        m = e["matrix"]
        s = (f"sheet_affine: x scale {m[0][0]:.5f}, y scale {m[1][1]:.5f}, "
             f"shear {m[0][1]:+.5f}")
    elif name == "lens_distortion":
        names = e.get("coefficient_names") or ["k1", "k2", "p1", "p2", "k3"]
        s = "lens_distortion (undeclared lens): " + ", ".join(
            f"{n} {c:+.4g}" for n, c in zip(names, e.get("coefficients", [])) if c)
        px, mm = e.get("corner_rms_px"), e.get("corner_rms_mm")
        if px and mm:
            s += (f"; marker corner RMS {px['before']:.3f} -> {px['after']:.3f} px "
                  f"({mm['before']:.4f} -> {mm['after']:.4f} mm)")
    elif name == "sheet_height":
        g = e.get("grid") or {}
        z = np.asarray(g.get("z_mm", [[0.0]]), float)
        sd = np.asarray(g.get("std_mm", [[np.nan]]), float)
        s = (f"sheet_height (the paper is not flat): marks up to "
             f"{e.get('max_abs_mark_height_mm', float('nan')):.3f} mm above/below the markers' "
             f"plane; map {float(np.nanmin(z)):+.3f} .. {float(np.nanmax(z)):+.3f} mm "
             f"(median std {float(np.nanmedian(sd)):.3f} mm)")
    else:
        s = name
    if "std" in e and e["std"] is not None:
        s += f" (+-{e['std']:.2g})"
    ev = e.get("evidence")
    if ev and evidence:
        b, a = ev["heldout_rms_mm"]
        s += f"; held-out RMS {b:.4f} -> {a:.4f} mm, F = {ev['F']:.1f}, p = {ev['p_value']:.2g}"
    return s


def survey_line(sv: dict) -> str:
    """loop.json ``survey`` (``vision-cal loop`` with a scene's survey block) in one line:
    the photos, the survey's verdict, whether the calibration measured against it."""
    used = ("used by the calibration (the print measured)" if sv.get("used") else
            f"not used ({sv.get('status')}): the print is not measured")
    return (f"survey of the blank sheet ({sv.get('n_used')} of {sv.get('n_photos')} photos): "
            f"{sv.get('verdict')}; {used}")
