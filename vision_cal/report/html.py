"""report.json, then report.html rendered from it (one self-contained file).

``build_report(run)`` collects the statistics (the calibration document plus what the
figures need) into a dict that is written as ``OUT/report.json``;
``render_html(report)`` makes the HTML from that dict alone, with every figure and photo
embedded as a data URI so the file opens from disk with no network.
"""

from __future__ import annotations

import base64
import html
import math
from pathlib import Path

import numpy as np

from vision_cal.dataset.io import atomic_write_json, atomic_write_text, read_json
from vision_cal.report import plots
from vision_cal.report.summary import describe_effect

MAX_PHOTOS = 40
THUMB_PX = 320
FULL_PX = 1200


def build_report(run, *, loop: dict | None = None) -> dict:
    """The report's statistics as a JSON-ready dict."""
    doc = dict(run.document)
    rep = {"format": "vision-cal/report/1", "dataset": str(run.session.root), "calibration": doc,
           "reference": run.session.raw.get("reference")}
    photos = []
    if run.measurement is not None:
        marks = run.measurement.marks
        mids = list(marks)
        mxy = np.array([marks[i].xy_mm for i in mids], float).reshape(-1, 2)
        for im in run.measurement.images:
            j = im.to_json()
            entry = {"file": j["file"], "path": str(run.session.root / j["file"]),
                     "status": j.get("status"), "reason": j.get("reason", "")}
            ids = getattr(im, "marker_ids", np.zeros(0))
            corners = getattr(im, "markers_px", np.zeros((0, 4, 2)))
            entry["markers_px"] = [[int(i), np.asarray(c).tolist()] for i, c in zip(ids, corners)]
            dots = []
            for xy, uv in zip(im.dots_xy_mm, im.dots_uv_px):
                name = None
                if len(mxy):
                    d = np.hypot(*(mxy - xy).T)
                    k = int(np.argmin(d))
                    name = mids[k] if d[k] < 0.5 else None
                dots.append([name, float(uv[0]), float(uv[1])])
            entry["dots_px"] = dots
            photos.append(entry)
    rep["photos"] = photos
    if loop:
        rep["loop"] = loop
    return rep


def _plain(v):
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, np.generic):
        return v.item()
    return v


def write_report(run, out_dir, *, loop: dict | None = None) -> Path:
    """Write OUT/report.json, then OUT/report.html from it; returns the HTML path."""
    out_dir = Path(out_dir)
    rep = build_report(run, loop=loop)
    jpath = atomic_write_json(out_dir / "report.json", rep)
    return atomic_write_text(out_dir / "report.html", render_html(read_json(jpath)))


def _uri(png: bytes, mime="image/png") -> str:
    return f"data:{mime};base64," + base64.b64encode(png).decode("ascii")


def _f(x, nd=4) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.{nd}f}"


def _table(head, rows) -> str:
    h = "".join(f"<th>{html.escape(str(c))}</th>" for c in head)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>"


def _photo_overlay(p: dict) -> tuple[str, str] | None:
    """(thumbnail URI, full-size URI) of a photo with its detections drawn, or None."""
    import cv2

    img = cv2.imread(p["path"], cv2.IMREAD_COLOR)
    if img is None:
        return None
    h, w = img.shape[:2]
    lw = max(1, int(round(w / 800)))
    for m in p.get("markers_px", []) or []:
        mid, corners = m[0], np.asarray(m[1], float).reshape(-1, 2)
        cv2.polylines(img, [np.round(corners).astype(np.int32)], True, (0, 200, 0), lw)
        cv2.putText(img, str(mid), tuple(np.round(corners[0]).astype(int)),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.5 * lw, (0, 160, 0), lw)
    for d in p.get("dots_px", []) or []:
        did, x, y = d[0], float(d[1]), float(d[2])
        cv2.circle(img, (int(round(x)), int(round(y))), 6 * lw, (0, 0, 255), lw)
        if did is not None:
            cv2.putText(img, str(did), (int(x) + 7 * lw, int(y) - 7 * lw),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.45 * lw, (0, 0, 230), lw)

    def enc(max_w):
        s = min(1.0, max_w / w)
        small = cv2.resize(img, (int(w * s), int(h * s)), interpolation=cv2.INTER_AREA)
        ok, buf = cv2.imencode(".jpg", small, [cv2.IMWRITE_JPEG_QUALITY, 75])
        return _uri(buf.tobytes(), "image/jpeg")

    return enc(THUMB_PX), enc(FULL_PX)


CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:2em auto;
max-width:1150px;color:#222;padding:0 1em}
h1{font-size:1.6em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #ddd;padding:.25em .6em;
text-align:right;font-variant-numeric:tabular-nums}th{background:#f4f4f4}
td:first-child,th:first-child{text-align:left}.ok{color:#070}.bad{color:#b00}
img.fig{max-width:100%;border:1px solid #eee}.thumbs{display:flex;flex-wrap:wrap;gap:8px}
.thumbs figure{margin:0;width:320px}.thumbs figcaption{font-size:.8em;color:#555}
.thumbs img{width:320px;cursor:zoom-in;border:1px solid #ccc}
#lightbox{display:none;position:fixed;inset:0;background:rgba(0,0,0,.85);z-index:9;
cursor:zoom-out;align-items:center;justify-content:center}
#lightbox img{max-width:96vw;max-height:96vh}.note{color:#555;font-size:.9em}
"""

JS = """
function showFull(el){var lb=document.getElementById('lightbox');
lb.querySelector('img').src=el.getAttribute('data-full');lb.style.display='flex';}
function hideFull(){document.getElementById('lightbox').style.display='none';}
"""


def render_html(rep: dict) -> str:
    """The report page, from report.json's contents alone."""
    doc = rep["calibration"]
    parts = [f"<h1>vision-cal report</h1><p class=note>dataset: {html.escape(rep['dataset'])}"
             f" &middot; method: {html.escape(doc.get('method', ''))} &middot; "
             f"{len(doc.get('marks', {}))} marks</p>"]
    # Table 2
    p, s, n = doc["params"], doc.get("std") or {}, doc.get("nominal") or {}
    ref = ((rep.get("reference") or {}).get("params")) or {}
    rows = []
    for label, key, k, unit in (("L1", "L1_mm", None, "mm"), ("L2", "L2_mm", None, "mm"),
                                ("z1", "joint_zero_deg", 0, "deg"),
                                ("z2", "joint_zero_deg", 1, "deg"),
                                ("base x", "base_mm", 0, "mm"), ("base y", "base_mm", 1, "mm")):
        def g(d):
            v = d.get(key) if d else None
            return v[k] if (v is not None and k is not None) else v
        row = [f"{label} [{unit}]", _f(g(n), 3), _f(g(p), 4), "&plusmn;" + _f(g(s), 4)]
        if ref:
            row.append(_f(g(ref), 1))
        rows.append(row)
    head = ["parameter", "nominal", "calibrated", "std (1 sigma)"]
    if ref:
        head.append(html.escape((rep.get("reference") or {}).get("label", "reference")))
    parts.append("<h2>Parameters (Table 2)</h2>" + _table(head, rows))
    r, v = doc.get("residual_rms_mm", {}), doc.get("validation_rms_mm", {})
    parts.append(_table(["RMS [mm]", "base model", "final model"], [
        ["residual (fitted marks)", _f(r.get("base_model")), _f(r.get("final_model"))],
        [f"held-out ({html.escape(str(v.get('kind', 'validation')))})",
         _f(v.get("base_model")), _f(v.get("final_model"))]]))
    if doc.get("noise_floor_mm") is not None:
        parts.append(f"<p>Measurement noise floor: {_f(doc['noise_floor_mm'])} mm (RMS, 2-D)</p>")
    ident = doc.get("identifiability") or {}
    if ident:
        parts.append(f"<p class=note>condition number of the scaled Jacobian "
                     f"{ident.get('condition_number', float('nan')):.3g}, rank "
                     f"{ident.get('rank')} of {ident.get('n_params')}</p>")
        hc = ident.get("high_correlations", [])
        if hc:
            parts.append("<p class=note>correlations above 0.9: " + ", ".join(
                f"{html.escape(c['a'])} ~ {html.escape(c['b'])} ({c['r']:+.3f})" for c in hc)
                + "</p>")
    # effects
    parts.append("<h2>Effects</h2>")
    eff = [e for e in doc.get("effects", []) if e["name"] != "unexplained"]
    parts.append("<ul>" + "".join(f"<li class=ok>{html.escape(describe_effect(e))}</li>"
                                  for e in eff) + "</ul>" if eff else
                 "<p>None found: the base model explains the marks.</p>")
    for e in doc.get("effects", []):
        if e["name"] == "unexplained":
            parts.append("<p class=bad>Unexplained structure: " +
                         html.escape("; ".join(e.get("seen", []))) + "</p>")
    diag = doc.get("diagnosis") or {}
    if diag.get("rejected"):
        parts.append("<h3>Candidates rejected</h3>" + _table(
            ["candidate", "held-out before [mm]", "held-out after [mm]", "F", "p", "dBIC", "why"],
            [[html.escape(e["label"]), _f(e["heldout_before_mm"]), _f(e["heldout_after_mm"]),
              _f(e["F"], 2), f"{e['p_value']:.2g}", _f(e["delta_bic"], 1),
              html.escape(e["reason"])] for e in diag["rejected"]]))
    pp = diag.get("per_photo_offsets") or []
    if pp:
        bad = [p for p in pp if p.get("flagged")]
        worst = max(pp, key=lambda p: float(np.hypot(*p["offset_mm"])))
        parts.append(f"<p>Per-photo offsets: {len(pp)} photos checked, "
                     + (f"<span class=bad>{len(bad)} shifted beyond the noise: " +
                        ", ".join(html.escape(p['file']) for p in bad) + "</span>" if bad else
                        "none shifted beyond the noise")
                     + f"; largest mean offset {np.hypot(*worst['offset_mm']):.4f} mm "
                     f"({html.escape(worst['file'])}).</p>")
    ni = ident.get("not_identifiable", [])
    if ni:
        parts.append("<h3>Not identifiable by this plan</h3><ul>" + "".join(
            f"<li>{html.escape(d['label'])}: {html.escape(d['fix'])}</li>" for d in ni) + "</ul>")
    # figures
    parts.append("<h2>Residuals</h2>")
    parts.append(f"<img class=fig alt='residual field' src='{_uri(plots.residual_field(doc))}'>")
    if all("joints_deg" in m for m in doc.get("marks", {}).values()):
        parts.append(f"<img class=fig alt='joint residuals' "
                     f"src='{_uri(plots.joint_residuals(doc))}'>")
    sh = plots.sheet_height(doc)
    if sh:
        parts.append("<h2>Sheet height</h2><p class=note>A raised paper moves a mark seen "
                     "through the marker mapping by about z r / H; against the printed grid "
                     "around it the mark keeps its paper position.</p>"
                     f"<img class=fig alt='sheet height' src='{_uri(sh)}'>")
    c = plots.circles(doc)
    if c:
        parts.append("<h2>Circle fits</h2><p class=note>Arc span limits a circle fit: the "
                     "centre's uncertainty grows like sigma / (1 - cos(span/2)).</p>"
                     f"<img class=fig alt='circle fits' src='{_uri(c)}'>")
    # Table 3
    loop = rep.get("loop") or {}
    if loop.get("targets"):
        parts.append("<h2>Targets (Table 3)</h2>")
        rows = [[html.escape(t["id"]), _f(t["target_mm"][0], 2), _f(t["target_mm"][1], 2),
                 _f(t.get("before_error_mm")), _f(t.get("after_error_mm"))]
                for t in loop["targets"]]
        parts.append(_table(["target", "x [mm]", "y [mm]", "error before [mm]",
                             "error after [mm]"], rows))
        tp = plots.targets(rep)
        if tp:
            parts.append(f"<img class=fig alt='target errors' src='{_uri(tp)}'>")
        for key in ("paths_png", "joints_png"):
            if loop.get(key):
                parts.append(f"<img class=fig alt='{key}' src='{_uri(base64.b64decode(loop[key]))}'>")
    # photos
    photos = rep.get("photos", [])
    skipped = [ph for ph in photos if ph.get("status") != "ok"]
    if photos:
        parts.append(f"<h2>Photos</h2><p>{len(photos) - len(skipped)} measured, "
                     f"{len(skipped)} skipped.</p>")
        if skipped:
            parts.append(_table(["photo", "reason"], [[html.escape(ph["file"]),
                                                       html.escape(ph.get("reason", ""))]
                                                      for ph in skipped]))
        figs = []
        for ph in [ph for ph in photos if ph.get("status") == "ok"][:MAX_PHOTOS]:
            ov = _photo_overlay(ph)
            if ov:
                figs.append(f"<figure><img src='{ov[0]}' data-full='{ov[1]}' "
                            f"onclick='showFull(this)' alt='{html.escape(ph['file'])}'>"
                            f"<figcaption>{html.escape(ph['file'])}</figcaption></figure>")
        if figs:
            parts.append("<div class=thumbs>" + "".join(figs) + "</div>")
    body = "\n".join(parts)
    return (f"<!doctype html><html lang=en><head><meta charset=utf-8><title>vision-cal report"
            f"</title><style>{CSS}</style><script>{JS}</script></head><body>{body}"
            "<div id=lightbox onclick='hideFull()'><img alt='full size'></div></body></html>\n")
